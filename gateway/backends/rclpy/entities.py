"""The rclpy backend's entities: a publisher, a subscription and a service served by the gateway,
the topics the gateway publishes to and takes from itself (``Held``), and QoS in rclpy's terms.
Each holds its backend (``backend.RclpyBackend``) and acts through it."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING

from ..base import Message, QoS
from .cdr import Slow
from .pump import ServiceServer, TopicReader

if TYPE_CHECKING:
    from .backend import RclpyBackend

log = logging.getLogger('rosgate.rclpy')


def fq_name(namespace: str, name: str) -> str:
    return namespace.rstrip('/') + '/' + name


def split_node(node: str) -> tuple[str, str]:
    """'/ns/name' -> ('name', '/ns'); 'name' -> ('name', '/')."""
    ns, _, name = ('/' + node.strip('/')).rpartition('/')
    return name, ns or '/'


class RclpyPublisher:
    def __init__(self, backend: RclpyBackend, topic: str, type: str, cls, publisher):
        self.topic, self.type = topic, type
        self._backend, self._cls, self._pub = backend, cls, publisher
        self._cdr = backend.convert.cdr_writer(cls)

    def publish(self, msg: Message) -> None:
        if self._pub is None:
            return
        data = None
        if self._cdr is not None:
            try:
                data = self._cdr(msg)
            except Slow:
                pass
        self._pub.publish(self._backend.convert.from_dict(self._cls, msg) if data is None else data)
        self._backend.published(self.topic)

    def destroy(self) -> None:
        if self._pub is not None:
            self._backend.node.destroy_publisher(self._pub)
            self._pub = None


class Held:
    """A topic the gateway is publishing to, whose readers the loop takes from (not the pump)."""

    __slots__ = ('owed', 'busy')

    def __init__(self):
        self.owed = 0       # messages published since the last take
        self.busy = True    # published to since the last cool-down check


class RclpySubscription:
    def __init__(self, backend: RclpyBackend, topic: str, type: str, callback: Callable[..., None],
                 with_cdr: bool = False):
        self.topic, self.type = topic, type
        self._backend, self._callback, self._with_cdr = backend, callback, with_cdr
        self.sub: TopicReader | None = None

    def deliver(self, item: tuple[Message, bytes | None]) -> None:    # on the loop
        if self.sub is not None:
            if self._with_cdr:
                self._callback(*item)
            else:
                self._callback(item[0])

    def want_cdr(self, wanted: bool) -> None:
        """A type with a compiled CDR reader is taken as CDR anyway; any other only while wanted."""
        if self.sub is not None:
            self.sub.keep_cdr = wanted and self._with_cdr

    def destroy(self) -> None:
        sub, self.sub = self.sub, None
        if sub is not None:
            readers = self._backend.readers.get(self.topic, [])
            if sub in readers:
                readers.remove(sub)
                if not readers:
                    del self._backend.readers[self.topic]
            self._backend.pump.remove(sub)


class RclpyService:
    """A service served by the gateway: requests come from the pump, answers go out from the loop."""

    def __init__(self, backend: RclpyBackend, name: str, type: str, cls, handler):
        self.name, self.type, self.cls = name, type, cls
        self._backend, self._handler = backend, handler
        self.srv: ServiceServer | None = None       # None once destroyed
        self.entity: ServiceServer | None = None    # kept: late answers still go out through it
        self.pending: set[asyncio.Task] = set()     # requests waiting for the gateway's answer

    def on_request(self, item) -> None:             # on the loop
        request, header = item
        backend = self._backend
        if self.srv is None:
            self.respond(header, None)
            return
        try:
            data = backend.convert.to_dict(request)
        except Exception as e:  # noqa: BLE001
            backend.report(f'service {self.name}', e)
            self.respond(header, None)
            return
        task = backend.loop.create_task(backend.serve(self.name, self._handler, data))
        self.pending.add(task)
        task.add_done_callback(lambda t: self._answered(header, t))

    def _answered(self, header, task: asyncio.Task) -> None:
        self.pending.discard(task)
        self.respond(header, None if task.cancelled() else task.result())

    def respond(self, header, data: Message | None) -> None:
        """Answer one caller; None: a default response."""
        response = self.cls.Response()
        if data is not None:
            try:
                response = self._backend.convert.from_dict(self.cls.Response, data)
            except Exception as e:  # noqa: BLE001
                self._backend.report(f'service {self.name}: bad response', e)
        handle = self.entity.handle
        try:
            with handle:
                handle.service_send_response(response, header.request_id)
        except Exception as e:  # noqa: BLE001 (the service is gone: its callers get nothing)
            log.debug('service %s: %s', self.name, e)

    def destroy(self) -> None:
        srv, self.srv = self.srv, None
        if srv is None:
            return
        backend = self._backend
        if backend._served.get(self.name) is self:
            del backend._served[self.name]
        if not self.pending:
            backend.pump.remove(srv)
            return
        # waiting callers get a default response now; the service goes once they have it
        for task in list(self.pending):
            task.cancel()
        backend.loop.call_later(0.5, backend.pump.remove, srv)


def ros_qos(qos: QoS):
    from rclpy.duration import Duration  # noqa: PLC0415
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415

    kwargs = {
        'history': HistoryPolicy.KEEP_ALL if qos.history_keep_all else HistoryPolicy.KEEP_LAST,
        'depth': max(1, qos.depth),
        'reliability': ReliabilityPolicy.RELIABLE if qos.reliable else ReliabilityPolicy.BEST_EFFORT,
        'durability': DurabilityPolicy.TRANSIENT_LOCAL if qos.transient_local else DurabilityPolicy.VOLATILE,
    }
    if qos.deadline:
        kwargs['deadline'] = Duration(nanoseconds=int(qos.deadline * 1e9))
    if qos.lifespan:
        kwargs['lifespan'] = Duration(nanoseconds=int(qos.lifespan * 1e9))
    return QoSProfile(**kwargs)
