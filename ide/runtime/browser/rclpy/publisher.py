"""rclpy.publisher for Python in the IDE page: an ``advertise`` of the topic on the page's
connection; each publish a ``publish`` op of the message as rosbridge JSON."""

from rclpy import _engine
from rclpy.qos import DurabilityPolicy


class Publisher:
    def __init__(self, node, msg_type, topic, qos_profile, callback_group=None):
        self._node = node
        self.msg_type = msg_type
        self._type = _engine.Engine.type_name(msg_type)
        self._topic = topic
        self.qos_profile = qos_profile
        self.callback_group = callback_group
        self._latch = qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
        self._destroyed = False
        engine = _engine.engine()
        others = engine.publishers.setdefault(topic, [])
        others.append(self)
        if len(others) == 1:
            engine.send({"op": "advertise", "id": engine.next_id("advertise", topic), "topic": topic,
                         "type": self._type, "latch": self._latch, "queue_size": max(1, qos_profile.depth)})

    @property
    def topic_name(self):
        return self._topic

    @property
    def topic(self):
        return self._topic

    def publish(self, msg):
        if not isinstance(msg, self.msg_type):
            raise TypeError("Expected {}, got {}".format(self.msg_type, type(msg)))
        if self._destroyed:
            raise RuntimeError("publisher of %s was destroyed" % self._topic)
        engine = _engine.engine()
        engine.send({"op": "publish", "id": engine.next_id("publish", self._topic), "topic": self._topic,
                     "msg": engine.to_json(msg), "latch": self._latch})

    def get_subscription_count(self):
        return len(_engine.Engine.rosapi("subscribers", {"topic": self._topic}).get("subscribers") or [])

    def assert_liveliness(self):
        pass

    def wait_for_all_acked(self, timeout=None):
        """True: the page's connection is ordered, and the gateway has the messages it sent."""
        return True

    @property
    def handle(self):
        return self

    def destroy(self):
        if self._destroyed:
            return
        self._destroyed = True
        engine = _engine.engine()
        others = engine.publishers.get(self._topic, [])
        if self in others:
            others.remove(self)
        if not others:
            engine.publishers.pop(self._topic, None)
            engine.send({"op": "unadvertise", "topic": self._topic})
