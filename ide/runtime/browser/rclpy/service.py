"""rclpy.service for Python in the IDE page: an ``advertise_service`` on the page's connection;
each call the gateway forwards waits for the executor, and the callback's response goes back as
the call's ``service_response``."""

import inspect
from collections import deque

from rclpy import _engine


class Service:
    def __init__(self, node, srv_type, srv_name, callback, callback_group, qos_profile):
        self._node = node
        self.srv_type = srv_type
        self._type = _engine.Engine.type_name(srv_type)
        self._name = srv_name
        self.callback = callback
        self.callback_group = callback_group
        self.qos_profile = qos_profile
        self._queue = deque()
        self._destroyed = False
        engine = _engine.engine()
        engine.services[srv_name] = self
        engine.send({"op": "advertise_service", "id": engine.next_id("advertise_service", srv_name),
                     "type": self._type, "service": srv_name})

    @property
    def service_name(self):
        return self._name

    @property
    def handle(self):
        return self

    def _receive(self, message):
        self._queue.append(message)

    def _has_work(self):
        return bool(self._queue)

    def _take(self):
        call = self._queue.popleft()

        def job():
            request = _engine.Engine.from_json(self.srv_type.Request, call.get("args") or {})
            try:
                response = self.callback(request, self.srv_type.Response())
            except BaseException:
                self._answer(call, None, "the service's callback raised an error")
                raise
            if inspect.iscoroutine(response):
                return self._finish(call, response)
            self._answer(call, response)
            return None
        return job

    async def _finish(self, call, coroutine):
        try:
            response = await coroutine
        except BaseException:
            self._answer(call, None, "the service's callback raised an error")
            raise
        self._answer(call, response)

    def _answer(self, call, response, error=None):
        engine = _engine.engine()
        answer = {"op": "service_response", "service": self._name, "id": call.get("id")}
        if error is None and not isinstance(response, self.srv_type.Response):
            error = "the service's callback returned %r, not a %s" % (type(response).__name__,
                                                                     self.srv_type.Response.__name__)
        if error is not None:
            engine.send({**answer, "values": error, "result": False})
            if response is not None:
                raise TypeError(error)
            return
        engine.send({**answer, "values": engine.to_json(response), "result": True})

    def send_response(self, response, header):
        self._answer(header, response)

    def destroy(self):
        if self._destroyed:
            return
        self._destroyed = True
        engine = _engine.engine()
        if engine.services.get(self._name) is self:
            del engine.services[self._name]
            engine.send({"op": "unadvertise_service", "service": self._name})
