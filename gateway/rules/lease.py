"""The driver lease (``--exclusive-control``): one client at a time commands each robot.

Command names are topics of the velocity types plus anything matching ``--control-glob``
(topics, services, actions). Each command name belongs to one *group*, which has its own lease:

- a station: the top namespace of a node that subscribes to a velocity topic in it (the sim's
  ``--fleet`` stations ``/s01`` ..., or ``/robot1``, ``/robot2`` of a real multi-robot graph);
- else a ``--control-glob`` pattern (``/turtle1/*`` is the group ``/turtle1``);
- else the gateway-wide group ``/``.

The first client to command in a group takes its lease, if the group is a station nobody owns or
one its person owns (``stations``); others are refused with a status error that names what resolves
it (Take, "Claim a robot", the teacher) and can watch. The lease is the person's, not the tab's:
while one client of a person holds it, another of hers (her teleop page after her IDE, her phone,
her run) takes it by commanding, quietly (measured in the first lesson: refusing her own other tab
sent a student to a red banner that named neither Take nor her tab). A station the teacher released
from a person (``Stations.is_barred``) is not hers to take, by a command or by Take, until she
claims again: her pages left open on it had taken it back within a second.
Publish std_msgs/String on /rosgate/control: "take [NS]" takes a free lease (an admin, or anyone
when --auth is off, takes it over from its holder, whose motion is stopped; another client of the
same person, such as her robot-side run, takes it quietly and, being a run, gives it back when it
ends); "take-if-free NS" takes it only when it is free, not stopped and nobody else's station (what
a page does by itself); "release [NS]" gives one back (all of yours without NS; an admin may free
another's, which also ends a stop); "stop NS" (admin) zeroes every command left moving in the group,
frees it and tells the pages of that station to stop their programs. A stop sticks: until the
station's owner (or an admin) sends "take NS", or an admin releases it, no client and no run moves
that robot. Leaving releases everything. Who drives is published, latched, on /rosgate/driver as
JSON: {"driver": <holder of "/"> | null, "drivers": {group: holder | null}, "stations": [...],
"stopped": {group: unix time}, "halted": {group: who stopped it, while the stop holds}}, a holder
being {"client", "name", "role", "remote", "since", "owner": whether it is the station's owner's,
"run": its run id or null; in a fleet of gateways, one driving through another gateway has
"elsewhere": true and only "name" and "owner"}; in a fleet, "fleet": {"gateway": its id,
"unreachable": unix time since when it cannot reach its database, or null}.
A station's other names (services, actions, other topics) are its holder's too: ``stationnames``.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from fnmatch import fnmatchcase

from protocol.errors import ProtocolError

from ..backends.base import QoS
from .access import StationGrants, is_gateway, role_of
from .policy import CONTROL_TOPIC
from .ports import Announcer, Subscribes

log = logging.getLogger('rosgate.lease')
from .safety import moving_command
from .settle import FleetLease, Wait
from .stations import Stations, person
from .stationnames import StationNames
from .stops import Stops
from .hooks import Hook

DRIVER_TOPIC = '/rosgate/driver'
STRING = 'std_msgs/msg/String'
ROOT = '/'
RESCAN_PERIOD = 2.0       # s between checks for new stations (announced when they change)


def who(session) -> str:
    name = session.attrs.get('name')
    return f'{name} (client {session.id})' if name else f'client {session.id}'


def glob_group(glob: str) -> str:
    """'/turtle1/*' -> '/turtle1'; other globs name their group as written."""
    return glob[:-2] if glob.endswith('/*') and glob.count('*') == 1 and len(glob) > 2 else glob


class Lease(FleetLease, Hook):
    def __init__(self, *, announce: Announcer, control: Subscribes, types: frozenset[str],
                 globs: tuple[str, ...] | None, grants: StationGrants, stations: Stations, stops: Stops,
                 fleet=None):
        """announce: where /rosgate/driver is published (and the gateway's own services, no
        station's); control: the backend, where the control topic is declared; stops: a driver
        who loses the lease stops, a Stop zeroes the group (``rules.stops``, with the lease's
        groups); fleet: store.fleet.Fleet, the other gateways' leases (rules.fleet)."""
        self.types, self.globs = types, globs or ()
        self.grants, self.stops = grants, stops
        self.owners = stations
        self.holders: dict[str, object] = {}     # group -> session
        self.since: dict[str, float] = {}
        self.stopped: dict[str, float] = {}      # group -> when an admin last stopped it
        self.halted: dict[str, str] = {}         # group -> who stopped it, until "take" by its owner
        self.lent: dict[str, object] = {}        # group -> the session a run of the same person took it from
        self.fleet = fleet
        self.settling: dict[str, tuple] = {}     # group -> (person, who, Wait): a free lease asked of PostgreSQL
        # a station's services, actions and other topics: the holder's
        self.names = StationNames(self, own_services=announce.own_services)
        self._driver = announce.own_topic(DRIVER_TOPIC, STRING, QoS(depth=1, transient_local=True))
        # declares the control topic so clients may publish to it without a type
        self._control = control.subscribe(CONTROL_TOPIC, STRING, lambda msg: None)
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
        return self.owners.stations()

    def group(self, name: str) -> str:
        for ns in self.stations():
            if name.startswith(ns + '/'):
                return ns
        for ns in self._known_groups():   # a Stop in force, a driver elsewhere: a group before the graph shows it
            if name.startswith(ns + '/'):
                return ns
        for g in self.globs:
            if fnmatchcase(name, g):
                return glob_group(g)
        return ROOT

    def _known_groups(self):
        yield from (g for g in self.halted if g != ROOT)
        if self.fleet is not None:
            yield from (name for kind, name in self.fleet.others if kind == 'lease' and name != ROOT)

    def group_of_namespace(self, ns: str) -> str:
        return self.group(ns.rstrip('/') + '/') if ns.strip('/') else ROOT

    def is_command(self, name: str, type: str | None = None) -> bool:
        return type in self.types or any(fnmatchcase(name, g) for g in self.globs)

    # --- commands -------------------------------------------------------------------------------

    def require(self, session, name: str, type: str | None = None, msg: dict | None = None) -> Wait | None:
        """Grant a free lease to a commanding client of the station's owner (or of a station nobody
        owns); refuse everyone but the holder. Nobody moves a stopped robot until its owner takes it
        again; zero commands (a page stopping its program) pass without taking the lease. In a
        fleet a free lease waits for PostgreSQL's word: the answer is then a ``Wait`` (settle.py).
        msg: the command (None: a moving one)."""
        if not self.is_command(name, type):
            return None
        if is_gateway(session) and msg is not None and not moving_command(msg):
            return None   # a stop the gateway publishes itself
        group = self.group(name)
        holder = self.holders.get(group)
        if holder is session:
            return None
        moving = msg is None or type not in self.types or moving_command(msg)   # only asked here: rare
        stopper = self.halted.get(group)
        if stopper is not None:
            if not moving and holder is None:
                return None
            raise ProtocolError(f'{name}: {stopper} stopped {group}; send "take {group}" (the Take button) to '
                                'drive it again')
        key = person(session)
        settling = self.settling.get(group)
        if settling is not None:       # someone here is asking PostgreSQL for it: hers wait with it
            if settling[0] == key:
                return settling[2]
            if not moving:
                return None
            raise ProtocolError(f'{name}: {settling[1]} is taking the driver lease for {group} (exclusive control); '
                                f'{self._way_out(session, group)}')
        if holder is not None and person(holder) == key:
            if moving:      # another page or run of the same person: her robot, without a word
                self._grant(group, session, quiet=True)
            return None
        if holder is None:
            elsewhere = self.elsewhere(group, key)
            if elsewhere is not None:   # even a zero: nothing of hers reaches a robot another drives
                where = '' if group == ROOT else f' {group}'
                raise ProtocolError(f'{name}: {elsewhere} is driving{where} through another gateway (exclusive '
                                    f'control); {self._way_out(session, group)}')
            owner = self.owners.owner(group)
            barred = self._walk_in_refusal(group, key) if owner is None else None
            if barred is None and (owner is None or owner.person == key):
                return self._grant_settled(group, session)
            if not moving:
                return None
            if barred is not None:
                raise ProtocolError(f'{name}: {barred}')
            raise ProtocolError(f'{name}: {group} is {owner.name}\'s station; press "Claim a robot" for your '
                                'own, or ask the teacher')
        where = '' if group == ROOT else f' {group}'
        raise ProtocolError(f'{name}: {who(holder)} is driving{where} (exclusive control); '
                            f'{self._way_out(session, group)}')

    def _walk_in_refusal(self, group: str, key: str) -> str | None:
        """Why person ``key`` may not take a station nobody owns: the teacher released it from her,
        someone else's booked slot is on, or hers there just ended (rules.stations); None: she may."""
        if self.owners.is_barred(group, key):
            return self._released(group)
        return self.owners.walk_in_refusal(group, key)

    def _way_out(self, session, group: str) -> str:
        """What resolves a refusal because someone else holds group's lease, for this client."""
        if self._may_override(session):
            return 'press Take to take over'
        if group in self.stations():
            return 'press "Claim a robot" for a robot of your own, or ask the teacher'
        return 'wait for them to release it, or ask the teacher'

    def _released(self, group: str) -> str:
        by = self.owners.released.get(group, {}).get('by', 'the teacher')
        return f'{by} released {group}: it is not your robot any more; press "Claim a robot" for one'

    def topic_refusal(self, key: str | None, topic: str, type: str | None) -> str | None:
        """Why something new that person ``key`` starts (a playback) could not command ``topic``
        now: a stop holds its group, someone drives it (even that person, from a page), or it is
        another person's station. None: it could."""
        if not self.is_command(topic, type):
            return None
        group = self.group(topic)
        where = '' if group == ROOT else f' {group}'
        stopper = self.halted.get(group)
        if stopper is not None:
            return f'{stopper} stopped{where}; send "take {group}" (the Take button) first'
        holder = self.holders.get(group)
        if holder is not None:
            return f'{who(holder)} is driving{where} (exclusive control); wait for "release"'
        owner = self.owners.owner(group)
        if owner is None and self.owners.is_barred(group, key):
            return self._released(group)
        if owner is not None and owner.person != key:
            return f'{group} is {owner.name}\'s station; claim a free robot, or ask the teacher'
        return self.owners.walk_in_refusal(group, key) if owner is None and key is not None else None

    def publish_hook(self, session, pub, msg, issued=None):
        if pub.topic == CONTROL_TOPIC:
            return self._command(session, str(msg.get('data', '')).split())
        if not self.is_command(pub.topic, pub.type):   # a station's other topics: its holder's (stationnames)
            why = self.names.refusal(session, pub.topic)
            if why is not None:
                raise ProtocolError(why)
            return msg
        return self.require(session, pub.topic, pub.type, msg) or msg

    def _may_override(self, session) -> bool:
        return self.grants.overrides(session)

    def may_take_over(self, role: str | None) -> bool:
        return self.grants.overrides(role)

    def run_refusal(self, key: str, role: str | None, ns: str) -> str | None:
        """Why a robot-side run of person ``key`` (starter's ``role``) could not drive namespace
        ``ns``, or None when it may (it then takes the lease, from its person's page quietly)."""
        group = self.group_of_namespace(ns)
        admin = self.grants.exempt(role)   # a signed-in admin: past a stop, a bar or an ended slot
        where = f' of {ns}' if ns else ''
        stopper = self.halted.get(group)
        if stopper is not None and not admin:
            return f'{stopper} stopped {group}; press Take (send "take {group}") to drive it again, then run'
        owner = self.owners.owner(group)
        if owner is None and self.owners.is_barred(group, key) and not admin:
            return self._released(group)
        if owner is not None and owner.person != key and not self.may_take_over(role):
            return f'{group} is {owner.name}\'s station; claim a free robot, or ask the teacher'
        barred = self.owners.walk_in_refusal(group, key) if owner is None and not admin else None
        if barred is not None:
            return barred
        holder = self.holders.get(group)
        if holder is not None and person(holder) != key and not self.may_take_over(role):
            return (f'{who(holder)} holds the driver lease{where} (exclusive control); a run needs it: wait for '
                    '"release" or ask an admin')
        return None

    def take(self, session, ns: str | None = None) -> None:
        """What "take NS" on the control topic does, for a client that does not send it itself
        (a robot-side run); ProtocolError when someone else drives and session may not take over."""
        self._command(session, ['take', ns] if ns else ['take'])

    def _command(self, session, words: list[str]) -> Wait | None:
        verb = words[0].lower() if words else ''
        if (verb not in ('take', 'take-if-free', 'release', 'stop') or len(words) > 2
                or (verb in ('stop', 'take-if-free') and len(words) != 2)):
            raise ProtocolError(f'{CONTROL_TOPIC} takes "take [NS]", "take-if-free NS", "release [NS]" or '
                                f'"stop NS", not {" ".join(words)!r}')
        if verb == 'release' and len(words) == 1:
            for group in [g for g, h in self.holders.items() if h is session]:
                self._grant(group, None)
            return
        group = self.group_of_namespace(words[1]) if len(words) == 2 else ROOT
        holder = self.holders.get(group)
        owner = self.owners.owner(group)
        barred = owner is None and self.owners.is_barred(group, person(session))
        mine = (owner is None and not barred) or (owner is not None and owner.person == person(session))
        ended = self.owners.walk_in_refusal(group, person(session)) if owner is None else None
        if ended is not None and verb.startswith('take') and not self._may_override(session):
            if verb == 'take-if-free':   # someone else's slot, or hers just ended (rules.bookings)
                return
            raise ProtocolError(ended)
        if verb == 'take-if-free':   # a page on its own station: never a stopped one, never another's
            if holder is None and mine and group not in self.halted and self.elsewhere(group, person(session)) is None:
                return self._grant_settled(group, session)
            return None
        if verb == 'stop':
            if not self._may_override(session):
                raise ProtocolError(f'only an admin can stop {group}')
            self.stopped[group] = round(time.time(), 3)
            if holder is not None:
                self._grant(group, None, by=session, why='stopped the robot and freed')
            self._halt(group, who(session))   # sticks until the owner's "take" or an admin's "release"
            self.stops.stop_group(group, self.group)
            self._announce()
            if self.fleet is not None and not self.fleet.confirmed():
                session.status('warning', f'{group} is stopped through this gateway; {self.fleet.why_unconfirmed()}, '
                                          'so the other gateways learn of the Stop when it is back')
            return None
        if verb == 'release':
            if holder is session:
                self._grant(group, None)
            elif self._may_override(session):
                if holder is not None:
                    self._grant(group, None, by=session, why='released')
                self._unhalt(group, end=who(session))   # and whoever drives it through another gateway
                self._announce()
            elif holder is not None:
                raise ProtocolError(f'{who(holder)} is driving{"" if group == ROOT else " " + group}; '
                                    'only an admin can release it')
            return
        # take
        if barred and not self._may_override(session):
            raise ProtocolError(self._released(group))
        stopper = self.halted.get(group)
        if stopper is not None and not mine and not self.grants.exempt(session):
            raise ProtocolError(f'{stopper} stopped {group}; only its owner ({owner.name}) can take it again, '
                                'or an admin release it: press "Claim a robot" for your own')
        if not mine and not self._may_override(session):
            raise ProtocolError(f'{group} is {owner.name}\'s station; only they or an admin can take it: press '
                                '"Claim a robot" for your own')
        elsewhere = self.elsewhere(group, person(session))
        if holder is None and elsewhere is not None and not self._may_override(session):
            raise ProtocolError(f'{elsewhere} is driving {group} through another gateway; only an admin can take '
                                f'over: {self._way_out(session, group)}')
        if holder is session:
            self._unhalt(group)
            self._announce()
        elif holder is None:
            self._unhalt(group)
            if elsewhere is not None:   # an admin's takeover: hers, whatever the others hold
                self._grant(group, session, by=session)
            else:
                return self._grant_settled(group, session)
        elif person(holder) == person(session):   # her run, or another tab of hers: quietly
            self._unhalt(group)
            self._grant(group, session)
            if session.attrs.get('run') is not None and holder.attrs.get('run') is None:
                self.lent[group] = holder
        elif self._may_override(session):
            self._unhalt(group)
            self._grant(group, session, by=session)
        else:
            raise ProtocolError(f'{who(holder)} is driving{"" if group == ROOT else " " + group}; '
                                f'only an admin can take over: {self._way_out(session, group)}')

    def hand_over(self, group: str, key: str | None, why: str) -> None:
        """A booked slot begins (key: its booker) or ends (None): the lease is freed unless a
        client of the booker holds it, a stop of the teacher's no longer holds, and whoever held
        it stops moving and is told why."""
        self._unhalt(group)
        holder = self.holders.get(group)
        if holder is not None and (key is None or person(holder) != key):
            self._grant(group, None)
            if not holder.closed:
                holder.status('warning', f'{why}: the driver lease for {group} is no longer yours; your '
                                         'commands were stopped')
        self._announce()

    def free(self, group: str, by) -> None:
        """A station given back (the teacher's Release, or its owner's): no holder and no stop, on
        any gateway."""
        holder = self.holders.get(group)
        if holder is not None:
            self._grant(group, None, by=None if holder is by else by, why='released')
        self._unhalt(group, end=who(by) if by is not None else 'the teacher')
        self._announce()

    def _grant_settled(self, group: str, session) -> Wait | None:
        """``_grant``, once PostgreSQL says the free lease is hers (in a fleet: settle.py)."""
        if self.fleet is not None and not self.fleet.holds('lease', group, person(session)):
            return self._settle(group, session, person(session), who(session))
        self._grant(group, session)
        return None

    def _grant(self, group: str, session, *, by=None, why: str = 'took over', quiet: bool = False) -> None:
        """Give the group's lease to session (None: free it); the previous holder stops moving.
        quiet: between two clients of one person, who are told nothing (they share her robot)."""
        previous = self.holders.get(group)
        self.lent.pop(group, None)
        if session is None:
            self.holders.pop(group, None)
        else:
            self.holders[group] = session
        self.since[group] = time.time()
        where = '' if group == ROOT else f' for {group}'
        if previous is not None and previous is not session and not previous.closed:
            self.stops.stop_session(previous, group, self.group)   # whoever gives up the lease, or loses it, stops moving
            if by is not None and by is not previous:
                previous.status('warning', f'{who(by)} {why} the driver lease{where}; your commands were stopped')
        if session is not None:
            session.status('info', f'you hold the driver lease as client {session.id}{where}'
                                   + (' (from another page of yours)' if quiet else ''))
        if self.fleet is not None:   # the others hear it; an admin's takeover wins over theirs
            if session is None:
                self.fleet.drop('lease', group)
            else:
                self.fleet.hold('lease', group, person(session), who(session), force=by is session)
        self._announce()

    def on_close(self, session) -> None:
        for group in [g for g, s in self.lent.items() if s is session]:
            del self.lent[group]
        held = [g for g, h in self.holders.items() if h is session]
        for group in held:
            lender = self.lent.pop(group, None)
            del self.holders[group]
            if self.fleet is not None:
                self.fleet.drop('lease', group)
            if lender is not None and not lender.closed and group not in self.halted:
                self._grant(group, lender)   # a run ended: its person's page drives again
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
            'remote': h.remote, 'since': round(self.since.get(group, 0.0), 3),
            'owner': self.owners.is_owner(h, group), 'run': h.attrs.get('run')}

    def refresh(self) -> None:
        """Announce again (another gateway's driver came or went)."""
        self._announce()

    def _announce(self) -> None:
        stations = self.stations()
        drivers = {g: None for g in stations}
        if self.fleet is not None:   # who drives through the fleet's other gateways
            drivers.update({g: {'client': None, 'name': h.who, 'role': None, 'remote': None, 'since': None,
                                'owner': self.owners.owner(g) is not None and self.owners.owner(g).person == h.person,
                                'run': None, 'elsewhere': True}
                            for g in stations if (h := self.fleet.held('lease', g)) is not None})
        drivers.update({g: self._info(g) for g in self.holders})
        info = {'driver': self._info(ROOT), 'drivers': drivers, 'stations': list(stations),
                'stopped': self.stopped, 'halted': self.halted}
        if self.fleet is not None:   # which gateway says so, and since when it cannot reach its database
            info['fleet'] = {'gateway': self.fleet.id, 'unreachable': self.fleet.unreachable}
        text = json.dumps(info)
        if text != self._announced:
            self._announced = text
            self._driver.publish({'data': text})

    def _rescan(self) -> None:
        """Stations come and go with the graph: announce when they change."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        self._announce()
        self._timer = loop.call_later(RESCAN_PERIOD, self._rescan)
