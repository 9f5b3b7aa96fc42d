"""The gateway: what all client sessions share (backend, shared subscriptions and publishers)."""

from __future__ import annotations

import asyncio
import inspect
import logging
import time
from typing import TYPE_CHECKING

from .backends.base import BackendError, QoS
from .fanout import TopicFanout
from .outbox import corked
from .policy import Policy

if TYPE_CHECKING:
    from .session import ClientSession
    from .settings import Settings

log = logging.getLogger('rosgate')


class SharedPublisher:
    """One backend publisher per topic, used by every client that advertised it."""

    def __init__(self, gateway: Gateway, topic: str, type: str, qos: QoS):
        self.gateway, self.topic, self.type, self.qos = gateway, topic, type, qos
        self.msgdef = gateway.backend.msg_def(type)
        self.publisher = gateway.backend.create_publisher(topic, type, qos)
        self.clients: set[int] = set()
        self._release: asyncio.TimerHandle | None = None

    def attach(self, session_id: int) -> None:
        self.clients.add(session_id)
        if self._release is not None:
            self._release.cancel()
            self._release = None

    def detach(self, session_id: int) -> None:
        self.clients.discard(session_id)
        if not self.clients and self._release is None:
            delay = self.gateway.settings.unregister_timeout
            self._release = asyncio.get_running_loop().call_later(delay, self._destroy)

    def _destroy(self) -> None:
        self._release = None
        if not self.clients:
            self.gateway.publishers.pop(self.topic, None)
            self.publisher.destroy()


class Gateway:
    def __init__(self, settings: Settings, backend):
        self.settings, self.backend = settings, backend
        self.sessions: dict[int, ClientSession] = {}
        self.fanouts: dict[str, TopicFanout] = {}
        self.publishers: dict[str, SharedPublisher] = {}
        self.started = time.time()
        self.policy = Policy(settings)
        self.service_owners: dict[str, ClientSession] = {}
        self.hooks: list = []          # objects with an optional on_close(session)
        self.on_client_count = None
        self.publish_hooks: list = []  # (session, SharedPublisher, msg) -> msg or None to drop
        if hasattr(backend, 'batch_scope'):   # a backend delivering messages in batches
            backend.batch_scope = corked      # sends each client its share in one write

    # --- topics ------------------------------------------------------------------------------

    def topic_type(self, topic: str) -> str | None:
        for name, type in self.backend.topics():
            if name == topic:
                return type
        return None

    def fanout(self, topic: str, type: str) -> TopicFanout:
        fan = self.fanouts.get(topic)
        if fan is None:
            fan = self.fanouts[topic] = TopicFanout(self, topic, type)
        elif fan.type != type:
            raise BackendError(f'topic {topic} is subscribed with type {fan.type}, not {type}')
        return fan

    def drop_fanout(self, fan: TopicFanout) -> None:
        if self.fanouts.get(fan.topic) is fan:
            del self.fanouts[fan.topic]
        fan.destroy()

    def publisher(self, topic: str, type: str, qos: QoS) -> SharedPublisher:
        pub = self.publishers.get(topic)
        if pub is None:
            pub = self.publishers[topic] = SharedPublisher(self, topic, type, qos)
        elif pub.type != type:
            raise BackendError(f'topic {topic} is already advertised with type {pub.type}, not {type}')
        return pub

    # --- lifecycle ---------------------------------------------------------------------------

    def client_count_changed(self) -> None:
        if self.on_client_count is not None:
            self.on_client_count()

    def add(self, session: ClientSession) -> None:
        self.sessions[session.id] = session

    def remove(self, session: ClientSession) -> None:
        self.sessions.pop(session.id, None)

    async def shutdown(self) -> None:
        for hook in self.hooks:   # e.g. stop commands, while publishers and clients still exist
            on_shutdown = getattr(hook, 'on_shutdown', None)
            if on_shutdown:
                try:
                    result = on_shutdown()
                    if inspect.isawaitable(result):
                        await result
                except Exception:
                    log.exception('shutdown hook failed')
        for session in list(self.sessions.values()):
            session.close_connection(1001, 'server shutting down')
        for fan in list(self.fanouts.values()):
            fan.destroy()
        self.fanouts.clear()
        for pub in list(self.publishers.values()):
            pub.publisher.destroy()
        self.publishers.clear()
