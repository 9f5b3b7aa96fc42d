"""Safety of live control: velocity clamps, and a zero command when a driving client goes away.

Velocity topics are those whose type is in ``types`` (Twist and TwistStamped by default). For
each client and velocity topic the gateway remembers the last command. When that client
disconnects or errors out while its last command was not zero, the zero command (the type's
default message; a header keeps its frame_id and gets the current stamp) is published at once.
A *stream* is three or more commands each within ``cmd_timeout`` of the one before (teleop,
a program loop); when a moving stream then goes silent for ``cmd_timeout``, zero is published
too. On shutdown every moving topic gets its zero before clients are closed.

A command is fresh or it is dropped. A client that stamps its commands (``"t"`` on ``publish``,
``rules.freshness``) has each moving command dropped when it waited longer than ``cmd_max_age``
beyond the fastest trip seen on its link, when it was made while its link was stalled (a client
that pings), or when it was made before the last stop of its stream (a dead-man stop, the lease's
release or the teacher's Stop): after a stop, motion resumes only with a command made after it.
A zero command always passes. Commands that carry no stamp (plain rosbridge clients) pass, unless
``require_stamp`` refuses their moving ones, except after a stop of their stream (the dead-man's, a
release, the teacher's Stop): the gateway pings that connection, and its moving commands are
dropped until the pong comes back (``freshness.Fence``): what it sent before it saw the ping,
a stalled link's backlog among them, never moves the robot.
"""

from __future__ import annotations

import asyncio
import logging
import math
import tomllib
from dataclasses import dataclass, field
from fnmatch import fnmatchcase

from protocol.convert import from_json
from protocol.errors import ProtocolError

from ..backends.base import QoS
from .access import is_gateway
from ..settings import SafetySettings
from .hooks import Hook
from .ports import Door, Messages, Parties

log = logging.getLogger('rosgate.safety')
DEFAULT_TYPES = SafetySettings.stop_types
STREAM_MIN = 3           # commands in a row that make a stream
SHUTDOWN_FLUSH = 0.5     # s at most to let stop commands reach subscribers before clients close
CMD_MAX_AGE = SafetySettings.cmd_max_age   # s a stamped moving command may have waited beyond its link's fastest trip
STALE_TELL = 5.0         # s between two warnings to one client about its dropped commands


@dataclass(frozen=True)
class Clamp:
    max_linear: float | None = None    # m/s, on the length of the linear vector
    max_angular: float | None = None   # rad/s, on the length of the angular vector


@dataclass
class VelocityLimits:
    default: Clamp = Clamp()
    topics: list[tuple[str, Clamp]] = field(default_factory=list)   # (topic glob, clamp), first match wins

    @classmethod
    def load(cls, path, default: Clamp = Clamp()) -> VelocityLimits:
        """[[limits]] tables with topic (a glob), max_linear and/or max_angular."""
        with open(path, 'rb') as f:
            data = tomllib.load(f)
        topics = []
        for i, item in enumerate(data.get('limits', [])):
            if not isinstance(item, dict) or not isinstance(item.get('topic'), str):
                raise ValueError(f'{path}: limits[{i}] needs a topic')
            values = {k: float(item[k]) for k in ('max_linear', 'max_angular') if k in item}
            if any(v < 0 for v in values.values()):
                raise ValueError(f'{path}: limits[{i}]: limits are not negative')
            topics.append((item['topic'], Clamp(**values)))
        return cls(default, topics)

    def for_topic(self, topic: str) -> Clamp:
        for glob, clamp in self.topics:
            if fnmatchcase(topic, glob):
                return clamp
        return self.default


def twist_part(msg: dict) -> dict | None:
    if 'linear' in msg and 'angular' in msg:
        return msg
    inner = msg.get('twist')
    return inner if isinstance(inner, dict) and 'linear' in inner else None


def _scale(vector: dict, limit: float | None, where: str) -> None:
    values = [vector.get(k, 0.0) for k in 'xyz']
    for k, v in zip('xyz', values):
        if not math.isfinite(v):
            raise ProtocolError(f'{where}.{k} is {v}: velocity commands must be finite')
    if limit is None:
        return
    length = math.sqrt(sum(v * v for v in values))
    if length > limit:
        factor = limit / length
        for k, v in zip('xyz', values):
            vector[k] = v * factor


def moving_command(value, key: str = '') -> bool:
    """Any non-zero number outside the header."""
    if key == 'header':
        return False
    if isinstance(value, dict):
        return any(moving_command(v, k) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return any(moving_command(v) for v in value)
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)):
        return value != 0
    return False


class Stream:
    __slots__ = ('type', 'msgdef', 'last', 'count', 'moving', 'frame_id', 'timer', 'floor')

    def __init__(self, type: str, msgdef):
        self.type, self.msgdef = type, msgdef
        self.last, self.count, self.moving = -math.inf, 0, False
        self.floor = -math.inf   # moving commands made at or before this (loop time) are dropped
        self.frame_id = None
        self.timer: asyncio.TimerHandle | None = None


class Safety(Hook):
    def __init__(self, *, door: Door, parties: Parties, messages: Messages, types=DEFAULT_TYPES,
                 stop_on_disconnect: bool = True, cmd_timeout: float = 1.0, limits: VelocityLimits | None = None,
                 cmd_max_age: float = CMD_MAX_AGE, require_stamp: bool = False):
        """door: where the zero commands are published (as the gateway's own, through the rules);
        parties: who is there (each stopped at shutdown); messages: the zero commands' definitions
        and stamps (the backend)."""
        self.door, self.parties, self.messages = door, parties, messages
        self.cmd_max_age, self.require_stamp = cmd_max_age, require_stamp
        self.stale = 0                                    # stamped commands dropped as stale
        self.types = frozenset(types)
        self.stop_on_disconnect, self.cmd_timeout = stop_on_disconnect, cmd_timeout
        self.limits = limits or VelocityLimits()
        self.streams: dict[int, dict[str, Stream]] = {}   # session id -> topic -> Stream
        self.stopped = False                              # set at shutdown
        self.stops = 0                                    # zero commands published

    # --- the publish hook ---------------------------------------------------------------------

    def publish_hook(self, session, pub, msg, issued=None):
        if pub.type not in self.types:
            return msg
        part = twist_part(msg)
        if part is not None:
            clamp = self.limits.for_topic(pub.topic)
            _scale(part['linear'], clamp.max_linear, 'linear')
            _scale(part['angular'], clamp.max_angular, 'angular')
        if is_gateway(session):
            return msg
        moving = moving_command(msg)
        if moving and not self._fresh(session, pub, issued):
            return None
        if self.stop_on_disconnect or self.cmd_timeout > 0 or issued is not None:
            self._track(session, pub, msg, moving, issued)
        return msg

    def _fresh(self, session, pub, issued: float | None) -> bool:
        """Whether a moving command may pass: made after its stream's last stop and not stale
        (stamped), or sent after the client saw the last stop (unstamped: ``freshness.Fence``)."""
        now = asyncio.get_running_loop().time()
        fence = getattr(session, 'fence', None)
        if issued is None:
            if self.require_stamp:
                raise ProtocolError(f'{pub.topic}: this gateway takes only stamped velocity commands '
                                    '(a "t" on publish: docs/protocol.md; --require-cmd-stamp)')
            if fence is None or not fence.up:
                return True
            why = 'it was sent before the client saw the robot stop (the gateway waits for its pong)'
            return self._drop(session, pub, why, now)
        stream = self.streams.get(session.id, {}).get(pub.topic)
        clock = getattr(session, 'clock', None)
        if stream is not None and issued <= stream.floor:
            why = 'it was made before the robot was stopped'
        elif clock is not None and clock.in_stall(issued):
            why = 'it was made while the link was stalled'
        elif self.cmd_max_age > 0 and now - issued > self.cmd_max_age:
            why = f'it waited {now - issued:.2f} s on the way (--cmd-max-age {self.cmd_max_age:g})'
        else:
            return True
        return self._drop(session, pub, why, now)

    def _drop(self, session, pub, why: str, now: float) -> bool:
        """A moving command dropped: counted, and the client told why (once per STALE_TELL)."""
        self.stale += 1
        told = session.attrs.get('stale_told', -math.inf)
        if now - told >= STALE_TELL:
            session.attrs['stale_told'] = now
            session.status('warning', f'a command on {pub.topic} was dropped: {why}', 'publish')
            log.info('client %d: a command on %s dropped: %s (%d stale commands dropped in all)',
                     session.id, pub.topic, why, self.stale)
        return False

    def _track(self, session, pub, msg, moving: bool, issued: float | None = None) -> None:
        topics = self.streams.setdefault(session.id, {})
        stream = topics.get(pub.topic)
        if stream is None or stream.type != pub.type:
            stream = topics[pub.topic] = Stream(pub.type, pub.msgdef)
        now = asyncio.get_running_loop().time()
        stream.count = stream.count + 1 if now - stream.last <= self.cmd_timeout else 1
        stream.last = now
        stream.moving = moving
        if not moving and issued is not None:   # a release: nothing made before it moves again
            stream.floor = max(stream.floor, issued)
        header = msg.get('header')
        if isinstance(header, dict):
            stream.frame_id = header.get('frame_id')
        if stream.moving and self.cmd_timeout > 0 and stream.count >= STREAM_MIN and stream.timer is None:
            self._arm(session, pub.topic, stream, self.cmd_timeout)

    def _arm(self, session, topic: str, stream: Stream, delay: float) -> None:
        stream.timer = asyncio.get_running_loop().call_later(delay, self._silence, session, topic, stream)

    def _silence(self, session, topic: str, stream: Stream) -> None:
        stream.timer = None
        if not stream.moving or session.closed or self.stopped:
            return
        left = stream.last + self.cmd_timeout - asyncio.get_running_loop().time()
        if left > 0.001:
            self._arm(session, topic, stream, left)
            return
        log.info('no command on %s for %.3g s from client %d: stopping', topic, self.cmd_timeout, session.id)
        self._stop(topic, stream)
        self._fence(session)

    # --- stopping -----------------------------------------------------------------------------

    def zero(self, stream: Stream) -> dict:
        value: dict = {}
        if any(f.name == 'header' for f in stream.msgdef.fields):
            sec, nanosec = self.messages.now()
            value['header'] = {'stamp': {'sec': sec, 'nanosec': nanosec}, 'frame_id': stream.frame_id or ''}
        return from_json(self.messages.defs, stream.msgdef, value)

    def _stop(self, topic: str, stream: Stream) -> None:
        stream.moving, stream.count = False, 0
        stream.floor = asyncio.get_running_loop().time()
        if stream.timer is not None:
            stream.timer.cancel()
            stream.timer = None
        door = self.door
        pub = door.publishers.get(topic)
        temporary = pub is None
        if temporary:   # the client's publisher is already gone: publish through a short-lived one
            pub = door.publisher(topic, stream.type, QoS())
            pub.attach(0)
        try:
            if door.publish(door.itself, pub, self.zero(stream)):
                self.stops += 1
        finally:
            if temporary:
                pub.detach(0)

    def zero_topics(self, topics) -> int:
        """Zero each (topic, type) of ``topics`` that is a velocity type, through the gateway's own
        publisher: what another gateway of a fleet left moving when it died (its streams were its own)."""
        count = 0
        for topic, type in topics:
            if type in self.types:
                self._stop(topic, Stream(type, self.messages.msg_def(type)))
                count += 1
        return count

    def stop_session(self, session, where=None) -> int:
        """Zero every velocity topic this client left moving (those ``where(topic)`` accepts,
        when given); returns how many."""
        count = 0
        now = asyncio.get_running_loop().time()
        for topic, stream in self.streams.get(session.id, {}).items():
            if where is not None and not where(topic):
                continue
            if stream.moving:
                self._stop(topic, stream)
                count += 1
            stream.floor = now   # what it sent before the stop, still on the way, does not move
        if count and not session.closed:
            self._fence(session)
        return count

    def _fence(self, session) -> None:
        """After a stop of its stream: the connection's unstamped moving commands wait for its
        pong (``freshness.Fence``); stamped ones keep the finer rule of their stamps."""
        fence = getattr(session, 'fence', None)
        if fence is not None:
            fence.raise_()

    # --- gateway hooks ------------------------------------------------------------------------

    def on_close(self, session) -> None:
        if self.stopped:
            return
        if self.stop_on_disconnect and self.stop_session(session):
            log.info('client %d went away while driving: stop commands published', session.id)
        for stream in self.streams.pop(session.id, {}).values():
            if stream.timer is not None:
                stream.timer.cancel()

    async def on_shutdown(self) -> None:
        count = 0
        for session in self.parties.everyone():
            count += self.stop_session(session)
        self.stopped = True
        if not count:
            return
        log.info('shutdown: %d stop commands published', count)
        loop = asyncio.get_running_loop()
        deadline = loop.time() + SHUTDOWN_FLUSH
        await asyncio.sleep(0)   # deliveries that hop through the loop (rclpy) land first
        while loop.time() < deadline and any(s.outbox.queued_bytes for s in self.parties.sessions.values()):
            await asyncio.sleep(0.005)
