"""rclpy.subscription for Python in the IDE page: a ``subscribe`` of the topic on the page's
connection; its messages wait (at most the profile's depth, the oldest dropped) until the
executor takes them."""

from collections import deque

from rclpy import _engine
from rclpy.qos import HistoryPolicy


class Subscription:
    def __init__(self, node, msg_type, topic, callback, callback_group, qos_profile, raw=False):
        if raw:
            raise NotImplementedError("raw subscriptions (serialized messages) do not run in the page")
        self._node = node
        self.msg_type = msg_type
        self._type = _engine.Engine.type_name(msg_type)
        self._topic = topic
        self.callback = callback
        self.callback_group = callback_group
        self.qos_profile = qos_profile
        keep_all = qos_profile.history == HistoryPolicy.KEEP_ALL or qos_profile.depth == 0
        self._queue = deque(maxlen=None if keep_all else qos_profile.depth)
        engine = _engine.engine()
        self._id = engine.next_id("subscribe", topic)
        engine.subscriptions.setdefault(topic, []).append(self)
        engine.send({"op": "subscribe", "id": self._id, "topic": topic, "type": self._type,
                     "queue_length": qos_profile.depth or 0})
        self._destroyed = False

    @property
    def topic_name(self):
        return self._topic

    @property
    def handle(self):
        return self

    def _receive(self, values):
        self._queue.append(values)

    def _has_work(self):
        return bool(self._queue)

    def _take(self):
        values = self._queue.popleft()
        msg = _engine.Engine.from_json(self.msg_type, values)
        return lambda: self.callback(msg)

    def destroy(self):
        if self._destroyed:
            return
        self._destroyed = True
        engine = _engine.engine()
        subs = engine.subscriptions.get(self._topic, [])
        if self in subs:
            subs.remove(self)
        if not subs:
            engine.subscriptions.pop(self._topic, None)
        engine.send({"op": "unsubscribe", "id": self._id, "topic": self._topic})
