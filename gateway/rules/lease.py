"""The driver lease (``--exclusive-control``): one client at a time commands each robot.

Command names are topics of the velocity types plus anything matching ``--control-glob``
(topics, services, actions). Each command name belongs to one *group*, which has its own lease:

- a station: the top namespace of a node that subscribes to a velocity topic in it (the sim's
  ``--fleet`` stations ``/s01`` ..., or ``/robot1``, ``/robot2`` of a real multi-robot graph);
- else a ``--control-glob`` pattern (``/turtle1/*`` is the group ``/turtle1``);
- else the gateway-wide group ``/``.

The first client to command in a group takes its lease; others are refused with a status error
and can watch. Publish std_msgs/String on /rosgate/control: "take [NS]" takes a free lease (an
admin, or anyone when --auth is off, takes it over from its holder, whose motion is stopped);
"release [NS]" gives one back (all of yours without NS; an admin may free another's); "stop NS"
(admin) zeroes every command left moving in the group, frees it and tells the pages of that
station to stop their programs; until they send "take NS", the clients connected then may not
move that robot again. Leaving releases everything. Who drives is published, latched,
on /rosgate/driver as JSON: {"driver": <holder of "/"> | null, "drivers": {group: holder | null},
"stations": [...], "stopped": {group: unix time}}, a holder being {"client", "name", "role",
"remote", "since"}.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import Callable
from fnmatch import fnmatchcase

from protocol.errors import ProtocolError

from ..backends.base import QoS
from .policy import CONTROL_TOPIC, GATEWAY_ROLE
from .safety import moving_command

DRIVER_TOPIC = '/rosgate/driver'
STRING = 'std_msgs/msg/String'
ROOT = '/'
STATIONS_TTL = 1.0        # s between looks at the graph for stations
RESCAN_PERIOD = 2.0       # s between checks for new stations (announced when they change)


def who(session) -> str:
    name = session.attrs.get('name')
    return f'{name} (client {session.id})' if name else f'client {session.id}'


def glob_group(glob: str) -> str:
    """'/turtle1/*' -> '/turtle1'; other globs name their group as written."""
    return glob[:-2] if glob.endswith('/*') and glob.count('*') == 1 and len(glob) > 2 else glob


def find_stations(backend, types: frozenset[str]) -> tuple[str, ...]:
    """Top namespaces of nodes that subscribe to a velocity topic inside their namespace."""
    found = set()
    for name, type in backend.topics():
        if type not in types:
            continue
        for node in backend.subscribers(name):
            top = node.strip('/').split('/')
            if len(top) > 1 and name.startswith(f'/{top[0]}/'):
                found.add(f'/{top[0]}')
    return tuple(sorted(found))


class Lease:
    def __init__(self, gateway, *, types: frozenset[str], globs: tuple[str, ...] | None,
                 takeover_role: str | None, on_lost: Callable[[object, str], None],
                 stop_group: Callable[[str], None] = lambda group: None):
        self.gateway, self.types, self.globs = gateway, types, globs or ()
        self.takeover_role, self.on_lost, self.stop_group = takeover_role, on_lost, stop_group
        self.holders: dict[str, object] = {}     # group -> session
        self.since: dict[str, float] = {}
        self.stopped: dict[str, float] = {}      # group -> when an admin last stopped it
        self.benched: dict[str, dict[int, str]] = {}   # group -> {session id: who stopped it}, until "take"
        self._stations: tuple[str, ...] = ()
        self._stations_at = -float('inf')
        backend = gateway.backend
        self._driver = gateway.own_topic(DRIVER_TOPIC, STRING, QoS(depth=1, transient_local=True))
        # declares the control topic so clients may publish to it without a type
        self._control = backend.subscribe(CONTROL_TOPIC, STRING, lambda msg: None)
        self._announced = None
        self._timer: asyncio.TimerHandle | None = None
        self._announce()
        self._rescan()

    @property
    def holder(self):
        """The holder of the gateway-wide group."""
        return self.holders.get(ROOT)

    # --- groups ---------------------------------------------------------------------------------

    def stations(self) -> tuple[str, ...]:
        now = time.monotonic()
        if now - self._stations_at > STATIONS_TTL:
            self._stations, self._stations_at = find_stations(self.gateway.backend, self.types), now
        return self._stations

    def group(self, name: str) -> str:
        for ns in self.stations():
            if name.startswith(ns + '/'):
                return ns
        for g in self.globs:
            if fnmatchcase(name, g):
                return glob_group(g)
        return ROOT

    def group_of_namespace(self, ns: str) -> str:
        return self.group(ns.rstrip('/') + '/') if ns.strip('/') else ROOT

    def is_command(self, name: str, type: str | None = None) -> bool:
        return type in self.types or any(fnmatchcase(name, g) for g in self.globs)

    # --- commands -------------------------------------------------------------------------------

    def require(self, session, name: str, type: str | None = None, msg: dict | None = None) -> None:
        """Grant a free lease to a commanding client; refuse everyone but the holder. A client an
        admin stopped may not move the robot until it takes it again; its zero commands (its page
        stopping the program) pass without taking the lease. msg: the command (None: a moving one)."""
        if not self.is_command(name, type):
            return
        if session.attrs.get('role') == GATEWAY_ROLE and msg is not None and not moving_command(msg):
            return   # a stop the gateway publishes itself
        group = self.group(name)
        holder = self.holders.get(group)
        if holder is session:
            return
        stopper = self.benched.get(group, {}).get(session.id)
        if stopper is not None:
            moving = msg is None or type not in self.types or moving_command(msg)   # only asked here: rare
            if not moving and holder is None:
                return
            raise ProtocolError(f'{name}: {stopper} stopped {group}; send "take {group}" (the Take button) to '
                                'drive it again')
        if holder is None:
            self._grant(group, session)
            return
        where = '' if group == ROOT else f' {group}'
        raise ProtocolError(f'{name}: {who(holder)} is driving{where} (exclusive control); watch, wait for '
                            f'"release", or ask an admin to take over')

    def refusal(self, name: str | None, topic: str, type: str | None) -> str | None:
        """Why something new that the person ``name`` starts (a playback) could not command
        ``topic`` now: someone drives its group (even that person from another connection), or an
        admin stopped the group while that person was connected and they have not taken it since.
        None: it could."""
        if not self.is_command(topic, type):
            return None
        group = self.group(topic)
        where = '' if group == ROOT else f' {group}'
        holder = self.holders.get(group)
        if holder is not None:
            return f'{who(holder)} is driving{where} (exclusive control); wait for "release"'
        benched = self.benched.get(group, {})
        stopper = next((benched[s.id] for s in self.gateway.everyone()
                        if s.id in benched and name is not None and s.attrs.get('name') == name), None)
        if stopper is not None:
            return f'{stopper} stopped{where}; send "take {group}" (the Take button) first'
        return None

    def publish_hook(self, session, pub, msg):
        if pub.topic == CONTROL_TOPIC:
            self._command(session, str(msg.get('data', '')).split())
            return None
        self.require(session, pub.topic, pub.type, msg)
        return msg

    def _may_override(self, session) -> bool:
        return self.may_take_over(session.attrs.get('role'))

    def may_take_over(self, role: str | None) -> bool:
        return self.takeover_role is None or role == self.takeover_role

    def holder_against(self, role: str | None, ns: str):
        """Who holds the lease of namespace ``ns`` such that a client of ``role`` could not take
        it (None: it is free, or ``role`` may take it over)."""
        return None if self.may_take_over(role) else self.holders.get(self.group_of_namespace(ns))

    def take(self, session, ns: str | None = None) -> None:
        """What "take NS" on the control topic does, for a client that does not send it itself
        (a robot-side run); ProtocolError when someone else drives and session may not take over."""
        self._command(session, ['take', ns] if ns else ['take'])

    def _command(self, session, words: list[str]) -> None:
        verb = words[0].lower() if words else ''
        if verb not in ('take', 'release', 'stop') or len(words) > 2 or (verb == 'stop' and len(words) != 2):
            raise ProtocolError(f'{CONTROL_TOPIC} takes "take [NS]", "release [NS]" or "stop NS", '
                                f'not {" ".join(words)!r}')
        if verb == 'release' and len(words) == 1:
            for group in [g for g, h in self.holders.items() if h is session]:
                self._grant(group, None)
            return
        group = self.group_of_namespace(words[1]) if len(words) == 2 else ROOT
        holder = self.holders.get(group)
        if verb == 'stop':
            if not self._may_override(session):
                raise ProtocolError(f'only an admin can stop {group}')
            self.stopped[group] = round(time.time(), 3)
            # a stop sticks: nobody connected now moves this robot again without taking it
            self.benched[group] = {s.id: who(session) for s in self.gateway.everyone() if s is not session}
            if holder is not None:
                self._grant(group, None, by=session, why='stopped the robot and freed')
            self.stop_group(group)
            self._announce()
            return
        if verb == 'take':
            self.benched.get(group, {}).pop(session.id, None)
        if holder is None or holder is session:
            if verb == 'take':
                self._grant(group, session)
            elif holder is session:
                self._grant(group, None)
        elif self._may_override(session):
            self._grant(group, session if verb == 'take' else None, by=session)
        else:
            raise ProtocolError(f'{who(holder)} is driving{"" if group == ROOT else " " + group}; '
                                'only an admin can take over')

    def _grant(self, group: str, session, *, by=None, why: str = 'took over') -> None:
        """Give the group's lease to session (None: free it); the previous holder stops moving."""
        previous = self.holders.get(group)
        if session is None:
            self.holders.pop(group, None)
        else:
            self.holders[group] = session
        self.since[group] = time.time()
        where = '' if group == ROOT else f' for {group}'
        if previous is not None and previous is not session and not previous.closed:
            self.on_lost(previous, group)   # whoever gives up the lease, or loses it, stops moving
            if by is not None and by is not previous:
                previous.status('warning', f'{who(by)} {why} the driver lease{where}; your commands were stopped')
        if session is not None:
            session.status('info', f'you hold the driver lease as client {session.id}{where}')
        self._announce()

    def on_close(self, session) -> None:
        for benched in self.benched.values():
            benched.pop(session.id, None)
        held = [g for g, h in self.holders.items() if h is session]
        for group in held:
            del self.holders[group]
        if held:
            self._announce()

    def on_shutdown(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    # --- who drives -----------------------------------------------------------------------------

    def _info(self, group: str) -> dict | None:
        h = self.holders.get(group)
        return None if h is None else {
            'client': h.id, 'name': h.attrs.get('name') or f'client {h.id}', 'role': h.attrs.get('role'),
            'remote': h.remote, 'since': round(self.since.get(group, 0.0), 3)}

    def _announce(self) -> None:
        stations = self.stations()
        drivers = {g: None for g in stations}
        drivers.update({g: self._info(g) for g in self.holders})
        text = json.dumps({'driver': self._info(ROOT), 'drivers': drivers, 'stations': list(stations),
                           'stopped': self.stopped})
        if text != self._announced:
            self._announced = text
            self._driver.publish({'data': text})

    def _rescan(self) -> None:
        """Stations come and go with the graph: announce when they change."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        self._stations_at = -float('inf')
        self._announce()
        self._timer = loop.call_later(RESCAN_PERIOD, self._rescan)
