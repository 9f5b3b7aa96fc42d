"""The graph as Foxglove sees it, shared by every Foxglove session of the gateway.

Each topic of the graph (hidden ones left out, as foxglove_bridge and ``ros2 topic list`` do) is a
channel: an id, its type as the schema name, its definition text (``ros2msg``, the type with every
dependency appended) as the schema, ``cdr`` as the encoding; each service (and each of the
gateway's own, such as a station's claim) likewise, with its request and response parts. A
schema is made once per (topic, type), for every session; an id is kept for as long as the
process runs, so a channel that goes and comes back with the same type keeps its id (the spec
lets clients cache by id). A type the gateway cannot describe is not offered (logged once).

The backends tell nobody when the graph changes (rosapi and the lease ask when they need to), so
while a Foxglove client is connected the hub looks every ``PERIOD``: new and gone topics and
services become advertise/unadvertise messages for the sessions allowed to see them, the
connection graph goes to the sessions that subscribed to it, and the parameters sessions
subscribed to are read (every ``PARAM_PERIOD``: on the rclpy backend each is a service call to
its node) and sent when they changed. Nothing runs when no Foxglove client is connected.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from protocol import foxglove as fg
from protocol.msgdefs import SrvDef

if TYPE_CHECKING:
    from .session import FoxgloveSession

log = logging.getLogger('rosgate.foxglove')
PERIOD = 1.0          # s between looks at the graph while a Foxglove client is connected
PARAM_PERIOD = 2.0    # s between reads of the parameters clients subscribed to
# s before a type the gateway could not describe is tried again: on rclpy a type the install lacks
# is asked of the graph's nodes, which may hold the loop for up to 3 s (backends/rclpy/graphtypes.py)
UNKNOWN_RETRY = 60.0
GONE = object()    # a parameter's value once it is unset


@dataclass(frozen=True, slots=True)
class Channel:
    id: int
    topic: str
    type: str
    wire: dict          # its entry in an advertise message


@dataclass(frozen=True, slots=True)
class Service:
    id: int
    name: str
    type: str
    srv: SrvDef
    wire: dict          # its entry in an advertiseServices message


@dataclass(frozen=True, slots=True)
class Graph:
    """Who publishes and subscribes each topic and provides each service (node names)."""
    published: dict[str, frozenset[str]]
    subscribed: dict[str, frozenset[str]]
    services: dict[str, frozenset[str]]


EMPTY = Graph({}, {}, {})


class Framer:
    """The message data frames of the message the fan-out is handing out now: its receive time
    read once for every Foxglove subscriber, and one frame per subscription id, shared by the
    clients that chose the same id. A frame is the 13-byte header and a copy of the payload (the
    id differs per subscription, and a websocket message is one buffer here): a 640x480 rgb8
    image copied for each of 3 viewers cost 0.26 ms each on the 2-core test machine, busy. Clients
    number their subscriptions from 0 in the order they subscribe (npm ws-protocol's FoxgloveClient,
    so Lichtblick and Foxglove), so a class opening the same layout shares one copy."""

    __slots__ = ('clock', 'payload', 'stamp', 'frames')

    def __init__(self, clock):
        self.clock = clock          # () -> (sec, nanosec): the backend's now
        self.payload: bytes | None = None
        self.stamp = 0
        self.frames: dict[int, bytes] = {}

    def frame(self, subscription: int, payload: bytes) -> bytes:
        if payload is not self.payload:   # the next message (held here, so no other can take its address)
            sec, nanosec = self.clock()
            self.payload, self.stamp, self.frames = payload, sec * 1_000_000_000 + nanosec, {}
        found = self.frames.get(subscription)
        if found is None:
            found = self.frames[subscription] = fg.message_data_header(subscription, self.stamp) + payload
        return found


class Hub:
    def __init__(self, gateway):
        self.gateway = gateway
        self.sessions: dict[int, FoxgloveSession] = {}
        self.channels: dict[str, Channel] = {}          # topic -> its channel now
        self.channel_ids: dict[int, Channel] = {}
        self.services: dict[str, Service] = {}          # name -> its service now
        self.service_ids: dict[int, Service] = {}
        self.session_id = str(time.time_ns())           # serverInfo's: a reconnecting client sees a restart
        self.values: dict[str, Any] = {}                # subscribed parameters' last values ('/node.param')
        self.framer = Framer(gateway.backend.now)       # message data frames for every session's Feed
        self._ids = itertools.count(1)
        self._known: dict[tuple, int] = {}              # (kind, name, type) -> its id, kept for a comeback
        self._unknown: dict[tuple, float] = {}          # (name, type) not described -> when to try again
        self._task: asyncio.Task | None = None
        self._params_read = 0.0

    # --- sessions ------------------------------------------------------------------------------

    def join(self, session: FoxgloveSession) -> None:
        """A new session: told the channels and services it may see; the hub looks at the graph
        from now on (and tells the others of what changed since they were told)."""
        self.tick_lists()
        self.sessions[session.id] = session
        session.offer(list(self.channels.values()), [], list(self.services.values()), [])
        if self._task is None:
            self._task = asyncio.ensure_future(self._run())

    def leave(self, session: FoxgloveSession) -> None:
        self.sessions.pop(session.id, None)
        if not self.sessions and self._task is not None:
            self._task.cancel()
            self._task = None
            self.values.clear()

    async def _run(self) -> None:
        while self.sessions:
            await asyncio.sleep(PERIOD)
            try:
                self.tick_lists()
                self.tick_graph()
                now = time.monotonic()
                if now - self._params_read >= PARAM_PERIOD:
                    self._params_read = now
                    await self.poll_parameters()
            except asyncio.CancelledError:
                raise
            except Exception:   # a graph query that failed: tried again next time
                log.exception('foxglove: looking at the graph failed')

    # --- channels and services -------------------------------------------------------------------

    def tick_lists(self) -> None:
        added, removed, s_added, s_removed = self.refresh()
        if added or removed or s_added or s_removed:
            for session in tuple(self.sessions.values()):
                session.offer(added, removed, s_added, s_removed)

    def refresh(self) -> tuple[list[Channel], list[Channel], list[Service], list[Service]]:
        """What changed in the graph's topics and services since the last look."""
        gw = self.gateway
        topics = dict(gw.backend.topics())
        removed = [c for t, c in self.channels.items() if topics.get(t) != c.type]
        for c in removed:
            del self.channels[c.topic], self.channel_ids[c.id]
        added = []
        for topic, type in topics.items():
            if topic not in self.channels and self._may_try(topic, type):
                channel = self._channel(topic, type)
                if channel is not None:
                    added.append(channel)
        services = dict(gw.backend.services())
        services.update((name, type) for name, (type, _) in gw.own_services.items())
        s_removed = [s for n, s in self.services.items() if services.get(n) != s.type]
        for s in s_removed:
            del self.services[s.name], self.service_ids[s.id]
        s_added = []
        for name, type in services.items():
            if name not in self.services and self._may_try(name, type):
                service = self._service(name, type)
                if service is not None:
                    s_added.append(service)
        return added, removed, s_added, s_removed

    def _id(self, kind: str, name: str, type: str) -> int:
        key = (kind, name, type)
        found = self._known.get(key)
        if found is None:
            found = self._known[key] = next(self._ids)
        return found

    def _may_try(self, name: str, type: str) -> bool:
        again = self._unknown.get((name, type))
        return again is None or time.monotonic() >= again

    def _described(self, name: str, type: str, describe):
        """describe() -> what it makes; None when the gateway does not know the type (logged the
        first time; tried again after UNKNOWN_RETRY)."""
        try:
            made = describe()
        except Exception as e:   # UnknownType, a type the backend cannot resolve: not offered
            if (name, type) not in self._unknown:
                log.warning('foxglove: %s is not offered: its type %s is not known here (%s)', name, type, e)
            self._unknown[(name, type)] = time.monotonic() + UNKNOWN_RETRY
            return None
        self._unknown.pop((name, type), None)
        return made

    def _channel(self, topic: str, type: str) -> Channel | None:
        backend = self.gateway.backend

        def make() -> Channel:
            msgdef = backend.msg_def(type)
            id = self._id('topic', topic, msgdef.type)
            return Channel(id, topic, msgdef.type, fg.channel(id, topic, msgdef.type, backend.full_text(msgdef)))

        channel = self._described(topic, type, make)
        if channel is not None:
            self.channels[topic] = self.channel_ids[channel.id] = channel
        return channel

    def _service(self, name: str, type: str) -> Service | None:
        backend = self.gateway.backend

        def make() -> Service:
            srv = backend.srv_def(type)
            id = self._id('service', name, srv.type)
            wire = fg.service(id, name, srv.type, (srv.request.type, backend.full_text(srv.request)),
                              (srv.response.type, backend.full_text(srv.response)))
            return Service(id, name, srv.type, srv, wire)

        service = self._described(name, type, make)
        if service is not None:
            self.services[name] = self.service_ids[service.id] = service
        return service

    # --- the connection graph ----------------------------------------------------------------------

    def tick_graph(self) -> None:
        watching = [s for s in self.sessions.values() if s.graph is not None]
        if watching:
            graph = self.graph()
            for session in watching:
                session.graph_changed(graph)

    def graph(self) -> Graph:
        backend = self.gateway.backend
        topics = [name for name, _ in backend.topics()]
        return Graph({t: frozenset(backend.publishers(t)) for t in topics},
                     {t: frozenset(backend.subscribers(t)) for t in topics},
                     {s: frozenset(backend.service_providers(s)) for s, _ in backend.services()})

    # --- parameters ------------------------------------------------------------------------------

    async def read(self, names) -> dict[str, Any]:
        """The values of parameters named '/node.param' that are set; a node that does not
        answer leaves its parameters out."""
        backend = self.gateway.backend
        names = list(names)

        async def one(name: str):
            node, param = fg.split_parameter(name)
            return await backend.get_param(node, param)

        got = await asyncio.gather(*(one(n) for n in names), return_exceptions=True)
        return {n: v for n, v in zip(names, got) if not isinstance(v, BaseException)}

    async def poll_parameters(self) -> None:
        wanted = set().union(*(s.param_subs for s in self.sessions.values()))
        if not wanted:
            self.values.clear()
            return
        values = await self.read(wanted)
        self.changed({n: values.get(n, GONE) for n in wanted})

    def changed(self, values: dict[str, Any]) -> None:
        """New values of parameters (GONE: unset now), to the sessions subscribed to those
        that differ from what was last sent."""
        fresh = {n: v for n, v in values.items() if self.values.get(n, GONE) != v or type(v) is not type(
            self.values.get(n, GONE))}
        for name, value in fresh.items():
            if value is GONE:
                self.values.pop(name, None)
            else:
                self.values[name] = value
        if not fresh:
            return
        for session in tuple(self.sessions.values()):
            mine = [{'name': n} if v is GONE else fg.foxglove_parameter(n, v)
                    for n, v in fresh.items() if n in session.param_subs]
            if mine:
                session.send(fg.parameter_values(mine))
