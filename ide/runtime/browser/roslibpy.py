"""roslibpy (the 2.1 API) for Python in the IDE page (Pyodide in a worker, ide/js/run/pyrun.js).

A textbook roslibpy program runs unchanged: ``Ros(host, port)`` whatever host it names goes
through the page's own connection; ``Topic``, ``Message``, ``Service``/``ServiceRequest``,
``ActionClient``/``Goal``, ``run()``, ``run_forever()``, ``close()``, ``terminate()``. The ops
are roslibpy's own (the same JSON, the same ``op:name:N`` ids); callbacks run in the program's
one thread whenever it blocks (``time.sleep``, a blocking call, ``run_forever``; see
rosgate_browser.pump), where roslibpy runs them on its reactor's thread.
"""

import json
import time
from collections import UserDict
from enum import Enum

import rosgate_browser as _page

__version__ = "2.1.0"   # the roslibpy whose API this follows
CONNECTION_TIMEOUT = 10
ROSAPI_TIMEOUT = 5

__all__ = ["Ros", "Message", "Header", "Time", "Topic", "Service", "ServiceRequest", "ServiceResponse",
           "ServiceException", "ActionClient", "Goal", "GoalStatus", "Feedback", "Result", "RosTimeoutError",
           "set_rosapi_timeout", "set_default_transport"]


class RosTimeoutError(TimeoutError):
    pass


class _Values(UserDict):
    def __init__(self, values=None):
        self.data = {}
        if values is not None:
            self.update(values)


class Message(_Values):
    """A ROS message (a dict)."""


class ServiceRequest(_Values):
    """The request of a service call."""


class ServiceResponse(_Values):
    """The response of a service call."""


class Goal(_Values):
    """The goal of an action."""


class Feedback(_Values):
    """An action's feedback."""


class Result(_Values):
    """An action's result: {"status": GoalStatus, "values": ...}."""


class GoalStatus(Enum):
    UNKNOWN = 0
    ACCEPTED = 1
    EXECUTING = 2
    CANCELING = 3
    SUCCEEDED = 4
    CANCELED = 5
    ABORTED = 6


class Time(UserDict):
    """ROS time: secs and nsecs."""

    def __init__(self, secs, nsecs):
        self.data = {"secs": self._ensure_int(secs), "nsecs": self._ensure_int(nsecs)}

    @staticmethod
    def _ensure_int(n):
        if isinstance(n, int):
            return n
        if isinstance(n, float) and n.is_integer():
            return int(n)
        raise ValueError("argument must be an integer")

    secs = property(lambda self: self.data["secs"])
    nsecs = property(lambda self: self.data["nsecs"])

    def is_zero(self):
        return self.data["secs"] == 0 and self.data["nsecs"] == 0

    def to_nsec(self):
        return self.data["secs"] * 10**9 + self.data["nsecs"]

    def to_sec(self):
        return self.data["secs"] + self.data["nsecs"] / 1e9

    @staticmethod
    def from_sec(float_secs):
        secs = int(float_secs)
        return Time(secs, int((float_secs - secs) * 10**9))

    @staticmethod
    def now():
        return Time.from_sec(time.time())


class Header(UserDict):
    """A ROS 1 std_msgs/Header."""

    def __init__(self, seq=None, stamp=None, frame_id=None):
        self.data = {"seq": seq, "stamp": Time(stamp["secs"], stamp["nsecs"]) if stamp else None,
                     "frame_id": frame_id}


class MessageEncoder(json.JSONEncoder):
    def default(self, o):
        if isinstance(o, UserDict):
            return dict(o)
        if isinstance(o, Enum):
            return o.value
        return super().default(o)


class ServiceException(Exception):
    """A service call that failed."""


class RosBridgeException(Exception):
    pass


def set_rosapi_timeout(timeout):
    global ROSAPI_TIMEOUT
    ROSAPI_TIMEOUT = timeout


def set_default_transport(name):
    """Every transport is the page's connection here."""


class EventEmitter:
    def __init__(self):
        self._events = {}

    def on(self, event, f=None):
        if f is None:
            return lambda g: self.on(event, g) or g
        self._events.setdefault(event, []).append(f)
        return f

    def once(self, event, f):
        def one(*args):
            self.off(event, one)
            f(*args)
        return self.on(event, one)

    def off(self, event, f):
        fs = self._events.get(event, [])
        if f in fs:
            fs.remove(f)

    def remove_all_listeners(self, event=None):
        if event is None:
            self._events.clear()
        else:
            self._events.pop(event, None)

    def emit(self, event, *args):
        for f in list(self._events.get(event, [])):
            f(*args)


class RosBridgeProtocol:
    """Encodes ops and hands the gateway's messages to their handlers, as roslibpy's does (the
    same ``_message_handlers`` table, "status" empty unless the program fills it)."""

    def __init__(self, *args, **kwargs):
        self.factory = None
        self._pending_service_requests = {}
        self._pending_action_requests = {}
        self._message_handlers = {
            "publish": self._handle_publish,
            "service_response": self._handle_service_response,
            "call_service": self._handle_service_request,
            "action_feedback": self._handle_action_feedback,
            "action_result": self._handle_action_result,
            "status": None,
        }

    def on_message(self, message):
        handler = self._message_handlers.get(message.get("op"))
        if handler:
            handler(Message(message))

    def send_message(self, payload):
        _page.send(payload)

    def send_close(self):
        _page.close()

    def send_ros_message(self, message):
        self.send_message(json.dumps(dict(message), cls=MessageEncoder))

    def register_message_handlers(self, operation, handler):
        if operation in self._message_handlers:
            raise RosBridgeException("Only one handler can be registered per operation")
        self._message_handlers[operation] = handler

    def send_ros_service_request(self, message, callback, errback):
        self._pending_service_requests[message["id"]] = (callback, errback)
        self.send_ros_message(message)

    def send_ros_action_goal(self, message, resultback, feedback, errback):
        self._pending_action_requests[message["id"]] = (resultback, feedback, errback)
        self.send_ros_message(message)

    def _handle_publish(self, message):
        self.factory.emit(message["topic"], message["msg"])

    def _handle_service_response(self, message):
        handlers = self._pending_service_requests.pop(message.get("id"), None)
        if not handlers:
            return   # another Ros of the program asked
        callback, errback = handlers
        if message.get("result") is False:
            if errback:
                errback(message.get("values"))
        elif callback:
            callback(ServiceResponse(message.get("values")))

    def _handle_service_request(self, message):
        self.factory.emit(message["service"], message)

    def _handle_action_feedback(self, message):
        handlers = self._pending_action_requests.get(message.get("id"))
        if handlers and handlers[1]:
            handlers[1](Feedback(message.get("values")))

    def _handle_action_result(self, message):
        handlers = self._pending_action_requests.pop(message.get("id"), None)
        if not handlers:
            return
        resultback, _, errback = handlers
        status = message.get("status")
        if status is None and isinstance(message.get("values"), dict):
            status = message["values"].get("status")
        results = {"status": GoalStatus(status if status in GoalStatus._value2member_map_ else 0),
                   "values": message.get("values", {})}
        if message.get("result") is False:
            if errback:
                errback(results)
        elif resultback:
            resultback(Result(results))


class _Manager:
    """roslibpy's event loop manager: here the program's own thread, run while it waits."""

    def run(self):
        pass

    def run_forever(self):
        while True:
            _page.pump(None)

    def call_later(self, delay, callback):
        _page.call_later(delay, callback)

    def call_in_thread(self, callback):
        _page.call_later(0, callback)

    def terminate(self):
        pass


class _Factory(EventEmitter):
    def __init__(self, url):
        super().__init__()
        self.url = url
        self.manager = _Manager()
        self.proto = None
        self.is_connected = False

    def connect(self):
        if self.proto is None:
            self.proto = RosBridgeProtocol()
            self.proto.factory = self
            _page.attach(self.proto)
            self.is_connected = True
            self.emit("connection")

    def on_ready(self, callback):
        if self.proto is not None:
            callback(self.proto)

    def disconnect(self):
        if self.proto is not None:
            proto, self.proto = self.proto, None
            self.is_connected = False
            _page.detach(proto)
            proto.send_close()
            self.emit("close", proto)


class Ros:
    """The connection to ROS: the IDE page's own, whatever host and port it names."""

    def __init__(self, host="localhost", port=None, is_secure=False, headers=None, transport=None):
        scheme = "wss" if is_secure else "ws"
        url = host if "://" in str(host) else "%s://%s:%s" % (scheme, host, port or 9090)
        self.factory = _Factory(url)
        self.is_connecting = False
        self.connect()

    @property
    def id_counter(self):
        return _page.next_id()

    @property
    def is_connected(self):
        return self.factory.is_connected

    def connect(self):
        self.factory.connect()

    def close(self, timeout=CONNECTION_TIMEOUT):
        if self.is_connected:
            self.emit("closing")
            self.factory.disconnect()

    def run(self, timeout=CONNECTION_TIMEOUT):
        self.connect()

    def run_forever(self):
        self.factory.manager.run_forever()

    def run_event_loop(self):
        self.run_forever()

    def call_in_thread(self, callback):
        self.factory.manager.call_in_thread(callback)

    def call_later(self, delay, callback):
        self.factory.manager.call_later(delay, callback)

    def terminate(self):
        self.close()

    def on(self, event_name, callback):
        self.factory.on(event_name, callback)

    def off(self, event_name, callback=None):
        if callback:
            self.factory.off(event_name, callback)
        else:
            self.factory.remove_all_listeners(event_name)

    def emit(self, event_name, *args):
        self.factory.emit(event_name, *args)

    def on_ready(self, callback, run_in_thread=True):
        def ready(proto):
            if run_in_thread:
                self.call_in_thread(callback)
            else:
                callback()
        self.factory.on_ready(ready)

    def send_on_ready(self, message):
        self.factory.on_ready(lambda proto: proto.send_ros_message(message))

    def call_sync_service(self, message, timeout):
        out, done = {}, _page.Event()

        def ok(result):
            out["result"] = result
            done.set()

        def failed(error):
            out["exception"] = error
            done.set()
        self.call_async_service(message, ok, failed)
        if not done.wait(timeout):
            raise RosTimeoutError("No service response received")
        return out

    def call_async_service(self, message, callback, errback):
        self.factory.on_ready(lambda proto: proto.send_ros_service_request(message, callback, errback))

    def call_async_action(self, message, resultback, feedback, errback):
        self.factory.on_ready(lambda proto: proto.send_ros_action_goal(message, resultback, feedback, errback))

    def set_status_level(self, level, identifier):
        self.send_on_ready(Message({"op": "set_level", "level": level, "id": identifier}))

    def _rosapi(self, name, type_, args, key, callback, errback):
        result = Service(self, "/rosapi/" + name, "rosapi/" + type_).call(
            ServiceRequest(args), callback, errback, timeout=ROSAPI_TIMEOUT)
        if callback:
            return None
        return result[key] if key else result

    def get_time(self, callback=None, errback=None):
        result = self._rosapi("get_time", "GetTime", {}, None, callback, errback)
        if callback:
            return None
        t = result["time"]
        return Time(t.get("secs", t.get("sec", 0)), t.get("nsecs", t.get("nanosec", 0)))

    def get_topics(self, callback=None, errback=None):
        return self._rosapi("topics", "Topics", {}, "topics", callback, errback)

    def get_topic_type(self, topic, callback=None, errback=None):
        return self._rosapi("topic_type", "TopicType", {"topic": topic}, "type", callback, errback)

    def get_services(self, callback=None, errback=None):
        return self._rosapi("services", "Services", {}, "services", callback, errback)

    def get_service_type(self, service_name, callback=None, errback=None):
        return self._rosapi("service_type", "ServiceType", {"service": service_name}, "type", callback, errback)

    def get_nodes(self, callback=None, errback=None):
        return self._rosapi("nodes", "Nodes", {}, "nodes", callback, errback)

    def get_action_servers(self, callback=None, errback=None):
        return self._rosapi("action_servers", "GetActionServers", {}, "action_servers", callback, errback)


class Topic:
    """Publish and/or subscribe to a topic (roslibpy.Topic)."""

    SUPPORTED_COMPRESSION_TYPES = ("png", "none")

    def __init__(self, ros, name, message_type, compression=None, latch=False, throttle_rate=0,
                 queue_size=100, queue_length=0, reconnect_on_close=True):
        self.ros, self.name, self.message_type = ros, name, message_type
        self.compression = compression or "none"
        if self.compression not in self.SUPPORTED_COMPRESSION_TYPES:
            raise ValueError("Unsupported compression type. Must be one of: " + str(self.SUPPORTED_COMPRESSION_TYPES))
        self.latch, self.throttle_rate = latch, throttle_rate
        self.queue_size, self.queue_length = queue_size, queue_length
        self.reconnect_on_close = reconnect_on_close
        self._subscribe_id = None
        self._advertise_id = None

    @property
    def is_advertised(self):
        return self._advertise_id is not None

    @property
    def is_subscribed(self):
        return self._subscribe_id is not None

    def subscribe(self, callback):
        if self._subscribe_id:
            return
        self._subscribe_id = "subscribe:%s:%d" % (self.name, self.ros.id_counter)
        self.ros.on(self.name, callback)
        self.ros.send_on_ready(Message({
            "op": "subscribe", "id": self._subscribe_id, "type": self.message_type, "topic": self.name,
            "compression": self.compression, "throttle_rate": self.throttle_rate,
            "queue_length": self.queue_length}))

    def unsubscribe(self):
        if not self._subscribe_id:
            return
        self.ros.off(self.name)
        self.ros.send_on_ready(Message({"op": "unsubscribe", "id": self._subscribe_id, "topic": self.name}))
        self._subscribe_id = None

    def publish(self, message):
        if not self.is_advertised:
            self.advertise()
        self.ros.send_on_ready(Message({
            "op": "publish", "id": "publish:%s:%d" % (self.name, self.ros.id_counter), "topic": self.name,
            "msg": dict(message), "latch": self.latch}))

    def advertise(self):
        if self.is_advertised:
            return
        self._advertise_id = "advertise:%s:%d" % (self.name, self.ros.id_counter)
        self.ros.send_on_ready(Message({
            "op": "advertise", "id": self._advertise_id, "type": self.message_type, "topic": self.name,
            "latch": self.latch, "queue_size": self.queue_size}))

    def unadvertise(self):
        if not self.is_advertised:
            return
        self.ros.send_on_ready(Message({"op": "unadvertise", "id": self._advertise_id, "topic": self.name}))
        self._advertise_id = None


class Service:
    """A service client, or a server (roslibpy.Service)."""

    def __init__(self, ros, name, service_type, reconnect_on_close=True):
        self.ros, self.name, self.service_type = ros, name, service_type
        self.reconnect_on_close = reconnect_on_close
        self._service_callback = None
        self._is_advertised = False

    @property
    def is_advertised(self):
        return self._is_advertised

    def call(self, request, callback=None, errback=None, timeout=None):
        """Blocks until the response when no callback is given (the program's callbacks run meanwhile)."""
        if self.is_advertised:
            return None
        message = Message({"op": "call_service", "id": "call_service:%s:%d" % (self.name, self.ros.id_counter),
                           "service": self.name, "args": dict(request)})
        if callback:
            self.ros.call_async_service(message, callback, errback)
            return None
        results = self.ros.call_sync_service(message, timeout)
        if "exception" in results:
            raise ServiceException(results["exception"])
        return results["result"]

    def advertise(self, callback):
        if self.is_advertised:
            return
        if not callable(callback):
            raise ValueError("Callback is not a valid callable")
        self._service_callback = callback
        self.ros.on(self.name, self._service_response_handler)
        self.ros.send_on_ready(Message({"op": "advertise_service", "type": self.service_type, "service": self.name}))
        self._is_advertised = True

    def unadvertise(self):
        if not self.is_advertised:
            return
        self.ros.send_on_ready(Message({"op": "unadvertise_service", "service": self.name}))
        self.ros.off(self.name, self._service_response_handler)
        self._is_advertised = False

    def _service_response_handler(self, request):
        response = ServiceResponse()
        success = self._service_callback(request["args"], response)
        call = Message({"op": "service_response", "service": self.name, "values": dict(response), "result": success})
        if "id" in request:
            call["id"] = request["id"]
        self.ros.send_on_ready(call)


class ActionClient:
    """A ROS 2 action client (roslibpy.ActionClient): send_goal returns the goal id at once;
    wait_goal blocks until its result (the program's callbacks run meanwhile)."""

    def __init__(self, ros, name, action_type, reconnect_on_close=True):
        self.ros, self.name, self.action_type = ros, name, action_type
        self.reconnect_on_close = reconnect_on_close
        self.wait_results = {}

    def send_goal(self, goal, resultback, feedback, errback):
        goal_id = "send_action_goal:%s:%d" % (self.name, self.ros.id_counter)
        event = self.wait_results[goal_id] = _page.Event()

        def result(values):
            event.set()
            if resultback:
                resultback(values)

        def error(values):
            event.set()
            if errback:
                errback(values)
        self.ros.call_async_action(Message({
            "op": "send_action_goal", "id": goal_id, "action": self.name, "action_type": self.action_type,
            "args": dict(goal), "feedback": True}), result, feedback, error)
        return goal_id

    def cancel_goal(self, goal_id):
        self.ros.send_on_ready(Message({"op": "cancel_action_goal", "id": goal_id, "action": self.name}))

    def wait_goal(self, goal_id, timeout=None):
        event = self.wait_results.get(goal_id)
        if event is None:
            raise ValueError("Unknown goal ID")
        if not event.wait(timeout):
            raise RosTimeoutError("Goal failed to receive result")
        self.wait_results.pop(goal_id, None)


class _Comm:
    """roslibpy.comm: its protocol class (the runtime looks at its handler table)."""
    RosBridgeProtocol = RosBridgeProtocol
    RosBridgeException = RosBridgeException


comm = _Comm()
