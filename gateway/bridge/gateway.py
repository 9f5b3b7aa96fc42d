"""The gateway: what all client sessions share (backend, shared subscriptions and publishers),
and the one door through which everything the process publishes for someone passes.

``Gateway.publish(sender, pub, msg)`` applies the rules (``rules``: the run guard, the driver lease,
velocity clamps and stream tracking) once, then publishes. A client's ``publish`` op, a playback,
a robot-side run (a client like any other) and the zero commands of a stop all come through it;
``SharedPublisher`` keeps its backend handle to itself. The gateway's own announcements
(``/client_count``, ``/rosgate/driver``, ``/rosgate/runs/...``) are ``own_topic`` publishers,
which clients may not publish to.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import time
from typing import TYPE_CHECKING

from ..backends.base import BackendError, QoS
from .doors import RuleDoors
from .fanout import TopicFanout
from .foxglove.hub import Hub
from protocol.errors import ProtocolError

from ..rules import GATEWAY_ROLE, Hooks
from ..rules.policy import Policy
from ..rules.settle import Wait
from ..store import Store

if TYPE_CHECKING:
    from .session import ClientSession
    from ..settings import Settings

log = logging.getLogger('rosgate')
_sender_ids = itertools.count(-1, -1)   # clients count up from 1; senders that are not clients down from -1


class SharedPublisher:
    """One backend publisher per topic, used by every client that advertised it."""

    def __init__(self, gateway: Gateway, topic: str, type: str, qos: QoS):
        self.gateway, self.topic, self.type, self.qos = gateway, topic, type, qos
        self.msgdef = gateway.backend.msg_def(type)
        self._handle = gateway.backend.create_publisher(topic, type, qos)   # published to only by Gateway.publish
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
            self._handle.destroy()


class Sender:
    """Someone the gateway publishes for who is not a websocket client: the gateway itself (its
    stops) or a person's playback. Shaped like a client session as far as the rules look."""

    def __init__(self, name: str, role: str | None, remote: str = '', person: str | None = None):
        self.id = next(_sender_ids)
        self.attrs = {'name': name, 'role': role}
        if person is not None:
            self.attrs['person'] = person   # whose station it may drive (rules.stations)
        self.remote = remote
        self.closed = False

    def status(self, level: str, msg: str, op: str | None = None, id: str | None = None) -> None:
        """What the rules tell a client as a status goes to the log."""
        log.info('%s: %s', self.attrs['name'], msg)


class Gateway:
    def __init__(self, settings: Settings, backend):
        self.settings, self.backend = settings, backend
        self.sessions: dict[int, ClientSession] = {}
        self.fanouts: dict[str, TopicFanout] = {}
        self.publishers: dict[str, SharedPublisher] = {}
        self.started = time.time()
        self.policy = Policy(settings)
        self.service_owners: dict[str, ClientSession] = {}
        self.hooks = Hooks()           # the parts following the gateway's events (rules.hooks), sealed once
        self.ruleset = None            # the rules in force (rules.compose), once installed
        self.rules: tuple = ()         # the publish door's: (sender, SharedPublisher, msg, issued) -> msg or None
        self.guards: tuple = ()        # (session, op) -> None, or raise ProtocolError to refuse the op
        self.senders: dict[int, Sender] = {}   # open senders that are not clients (playbacks)
        # the gateway's own services besides rosapi (the stations' claims): name -> (type, answer),
        # answer(session, request) -> response values, knowing who calls
        self.own_services: dict[str, tuple[str, object]] = {}
        self.itself = Sender('the gateway', GATEWAY_ROLE)
        self._client_count = None
        self._store: Store | None = None
        self.images_rendered = 0       # images made to measure (fan-out), in /health: one per frame and size
        self.foxglove = Hub(self)      # the graph as the Foxglove sessions see it (bridge.foxglove)

    def rule_doors(self) -> RuleDoors:
        """What ``rules.compose`` hands on to the rules' parts (``rules.ports``): never the Gateway."""
        return RuleDoors(self)

    def install(self, rules) -> None:
        """Puts the rules in force (``rules.compose``), once, before the first client. Their parts
        hear events once ``hooks.seal`` is given them with the others' (``server.start``)."""
        if self.ruleset is not None:
            raise RuntimeError('the rules are installed once')
        self.ruleset, self.policy = rules, rules.policy
        self.rules, self.guards = rules.publish, rules.guards

    @property
    def store(self) -> Store:
        """The one database (bookings, history), opened on first use."""
        if self._store is None:
            self._store = Store(self.settings.storage.db_url)
        return self._store

    # --- topics ------------------------------------------------------------------------------

    def topic_type(self, topic: str) -> str | None:
        for name, type in self.backend.topics(hidden=True):   # a hidden topic, when named, too
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

    def open_publisher(self, sender, topic: str, type: str, qos: QoS) -> SharedPublisher:
        """A publisher for a sender that is not a client: the name globs and roles apply as to
        a client's advertise (ProtocolError when they refuse)."""
        self.policy.check(sender, 'publish', topic, 'advertise', None)
        pub = self.publisher(topic, type, qos)
        pub.attach(sender.id)
        return pub

    def publish(self, sender, pub: SharedPublisher, msg: dict, issued: float | None = None,
                id: str | None = None) -> bool:
        """The one door: the rules, once, then the backend. False when a rule dropped the
        message; a ProtocolError when one refused it. ``issued``: when the sender made the
        message, on the loop's clock, when it says (a client's stamped command, ``rules.freshness``).
        A rule may answer ``Wait`` (a free lease of a fleet asked of PostgreSQL, rules.settle): the
        message waits, nothing else does, and it asks that rule again when the word comes (True
        then; a refusal later is a status to the sender naming ``id``, the publish op's)."""
        return self._through(0, sender, pub, msg, issued, id)

    def _through(self, first: int, sender, pub: SharedPublisher, msg: dict, issued, id) -> bool:
        rules = self.rules
        for i in range(first, len(rules)):
            out = rules[i](sender, pub, msg, issued)
            if out is None:
                return False
            if type(out) is Wait:
                out.then(lambda why, i=i, msg=msg: self._resume(i, sender, pub, msg, issued, id, why))
                return True
            msg = out
        pub._handle.publish(msg)
        return True

    def _resume(self, first: int, sender, pub: SharedPublisher, msg: dict, issued, id, why: str | None) -> None:
        """A message that waited: the rules asked again from the one that made it wait (or refused)."""
        if sender.closed:            # its client is gone: nothing of it moves a robot now
            return
        try:
            if why is not None:
                raise ProtocolError(f'{pub.topic}: {why}')
            self._through(first, sender, pub, msg, issued, id)
        except Exception as e:
            report = getattr(sender, 'report', None)
            if report is not None:
                report('publish', id, e)
            else:
                sender.status('error', str(e))

    def own_topic(self, topic: str, type: str, qos: QoS):
        """A publisher of the gateway's own announcements; clients' publish ops on the topic
        are refused (``rules.policy``)."""
        return self.backend.create_publisher(topic, type, qos)

    def own_service(self, name: str, type: str, answer) -> None:
        """A service the gateway answers itself, with the caller's session; clients may not
        advertise one of the same name."""
        self.own_services[name] = (type, answer)

    def drop_own_service(self, name: str) -> None:
        self.own_services.pop(name, None)

    # --- senders that are not clients ---------------------------------------------------------

    def open_sender(self, name: str, role: str | None, remote: str = '', person: str | None = None) -> Sender:
        sender = Sender(name, role, remote, person)
        self.senders[sender.id] = sender
        return sender

    def close_sender(self, sender: Sender) -> None:
        """What a client's leaving does for a sender: its leases go, its moving commands stop."""
        if sender.closed:
            return
        sender.closed = True
        self.senders.pop(sender.id, None)
        self.left(sender)

    def left(self, who) -> None:
        """Tell the hooks (lease, safety, runs, ...) that a client or sender is gone."""
        self.hooks.close(who)

    def everyone(self) -> list:
        """Every client session and open sender."""
        return [*self.sessions.values(), *self.senders.values()]

    # --- lifecycle ---------------------------------------------------------------------------

    def count_clients(self) -> None:
        """As rosbridge: /client_count (std_msgs/Int32) and /connected_clients, both latched."""
        if self._client_count is None:
            latched = QoS(depth=1, transient_local=True)
            count = self.own_topic('/client_count', 'std_msgs/msg/Int32', latched)
            try:
                clients = self.own_topic('/connected_clients', 'rosbridge_msgs/msg/ConnectedClients', latched)
            except (LookupError, BackendError):   # a ROS install without rosbridge_msgs
                clients = None
            self._client_count = count, clients
        count, clients = self._client_count
        count.publish({'data': len(self.sessions)})
        if clients is not None:
            clients.publish({'clients': [
                {'ip_address': s.remote, 'connection_time': {'sec': s.connected_at[0], 'nanosec': s.connected_at[1]}}
                for s in self.sessions.values()]})

    def add(self, session: ClientSession) -> None:
        self.sessions[session.id] = session

    def remove(self, session: ClientSession) -> None:
        self.sessions.pop(session.id, None)

    async def shutdown(self) -> None:
        await self.hooks.shutdown()   # e.g. stop commands, while publishers and clients still exist
        for session in list(self.sessions.values()):
            session.close_connection(1001, 'server shutting down')
        for fan in list(self.fanouts.values()):
            fan.destroy()
        self.fanouts.clear()
        if self._store is not None:
            self._store.close()   # after the hooks, which may have written their last batch
        for sender in list(self.senders.values()):
            self.close_sender(sender)
        for pub in list(self.publishers.values()):
            pub._handle.destroy()
        self.publishers.clear()
