"""rclpy.client for Python in the IDE page: a call is a ``call_service`` op on the page's
connection; its ``service_response`` completes the future (a failed call, e.g. no such service
after the gateway's wait, completes it with an exception that names the service)."""

import time

from rclpy import _engine
from rclpy.task import Future


class ServiceCallError(RuntimeError):
    """The gateway answered a call with a failure (no such service, the server failed ...)."""


class Client:
    def __init__(self, node, srv_type, srv_name, qos_profile, callback_group):
        self._node = node
        self.srv_type = srv_type
        self._type = _engine.Engine.type_name(srv_type)
        self._name = srv_name
        self.qos_profile = qos_profile
        self.callback_group = callback_group
        self._pending = {}             # op id -> future
        self._destroyed = False

    @property
    def service_name(self):
        return self._name

    @property
    def handle(self):
        return self

    def call_async(self, request):
        if not isinstance(request, self.srv_type.Request):
            raise TypeError("Expected {}, got {}".format(self.srv_type.Request, type(request)))
        engine = _engine.engine()
        op_id = engine.next_id("call_service", self._name)
        future = Future(executor=getattr(self._node, "executor", None))
        self._pending[op_id] = future

        def answered(m):
            if m.get("op") == "status" and m.get("level") != "error":
                return
            engine.replies.pop(op_id, None)
            self._pending.pop(op_id, None)
            if future.done():
                return
            if m.get("op") == "service_response" and m.get("result") is not False:
                future.set_result(engine.from_json(self.srv_type.Response, m.get("values") or {}))
            else:
                why = m.get("values") if m.get("op") == "service_response" else m.get("msg")
                future.set_exception(ServiceCallError("service %s: %s" % (self._name, why)))
        engine.replies[op_id] = answered
        engine.send({"op": "call_service", "id": op_id, "service": self._name, "type": self._type,
                     "args": engine.to_json(request)})
        return future

    def call(self, request, timeout_sec=None):
        """Blocks until the response (the program's messages come in meanwhile; callbacks wait for
        the executor); None when timeout_sec passes first."""
        future = self.call_async(request)
        end = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not future.done():
            left = None if end is None else end - time.monotonic()
            if left is not None and left <= 0:
                self.remove_pending_request(future)
                return None
            _engine.pump(left)
        return future.result()

    def remove_pending_request(self, future):
        for op_id, f in list(self._pending.items()):
            if f is future:
                del self._pending[op_id]
                _engine.engine().replies.pop(op_id, None)

    def service_is_ready(self):
        try:
            return bool(_engine.Engine.rosapi("service_type", {"service": self._name}).get("type"))
        except (LookupError, TimeoutError):
            return False

    def wait_for_service(self, timeout_sec=None):
        end = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not self.service_is_ready():
            left = None if end is None else end - time.monotonic()
            if left is not None and left <= 0:
                return False
            time.sleep(0.1 if left is None else min(0.1, left))
        return True

    def destroy(self):
        self._destroyed = True
        engine = _engine.engine()
        for op_id in self._pending:
            engine.replies.pop(op_id, None)
        self._pending.clear()
