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
from .access import StationGrants, is_gateway
from .leasetable import Command, Holder, LeaseFacts, Owning, Verdict
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


# The words of each refusal, by command and reason ({...}: what ``_Said`` looks up, when asked);
# a bar and an ended slot are worded alike for every command (``SAID``) but a page's command.
C, V = Command, Verdict
CLAIM_A_FREE_ONE = '{group} is {owner}\'s station; claim a free robot, or ask the teacher'
SAID = {V.RELEASED: '{released}', V.ENDED: '{ended}'}
WORDS = {
    (C.DRIVE, V.STOPPED): '{name}: {stopper} stopped {group}; send "take {group}" (the Take button) to drive it again',
    (C.DRIVE, V.BEING_TAKEN): '{name}: {settler} is taking the driver lease for {group} (exclusive control); {way_out}',
    (C.DRIVE, V.ELSEWHERE): '{name}: {elsewhere} is driving{where} through another gateway (exclusive control); '
                            '{way_out}',
    (C.DRIVE, V.RELEASED): '{name}: {released}',
    (C.DRIVE, V.ENDED): '{name}: {ended}',
    (C.DRIVE, V.OTHERS_STATION): '{name}: {group} is {owner}\'s station; press "Claim a robot" for your own, or ask '
                                 'the teacher',
    (C.DRIVE, V.OTHER_DRIVES): '{name}: {holder} is driving{where} (exclusive control); {way_out}',
    (C.TAKE, V.STOPPED_OWNER_ONLY): '{stopper} stopped {group}; {owner_only}',
    (C.TAKE, V.OTHERS_STATION): '{group} is {owner}\'s station; only they or an admin can take it: press "Claim a '
                                'robot" for your own',
    (C.TAKE, V.ELSEWHERE): '{elsewhere} is driving {group} through another gateway; only an admin can take over: '
                           '{way_out}',
    (C.TAKE, V.OTHER_DRIVES): '{holder} is driving{where}; only an admin can take over: {way_out}',
    (C.STOP, V.ADMIN_STOPS): 'only an admin can stop {group}',
    (C.RELEASE, V.ADMIN_RELEASES): '{holder} is driving{where}; only an admin can release it',
    (C.RUN, V.STOPPED_TAKE_FIRST): '{stopper} stopped {group}; press Take (send "take {group}") to drive it again, '
                                   'then run',
    (C.RUN, V.OTHERS_STATION): CLAIM_A_FREE_ONE,
    (C.RUN, V.HOLDS_LEASE): '{holder} holds the driver lease{of_ns} (exclusive control); a run needs it: wait for '
                            '"release" or ask an admin',
    (C.PLAY, V.STOPPED): '{stopper} stopped{where}; send "take {group}" (the Take button) first',
    (C.PLAY, V.DRIVING): '{holder} is driving{where} (exclusive control); wait for "release"',
    (C.PLAY, V.OTHERS_STATION): CLAIM_A_FREE_ONE,
}


class _Said(dict):
    """What a refusal's words name, looked up when they name it."""

    def __init__(self, lease, group: str, session, key: str | None, name: str, ns: str):
        super().__init__(group=group, name=name, where='' if group == ROOT else f' {group}',
                         of_ns=f' of {ns}' if ns else '')
        self.lease, self.session, self.key = lease, session, key

    def __missing__(self, what: str) -> str:
        return getattr(self, what)()

    def stopper(self) -> str:
        return self.lease.halted.get(self['group'])

    def owner(self) -> str:
        o = self.lease.owners.owner(self['group'])
        return 'nobody' if o is None else o.name

    def owner_only(self) -> str:
        """Who may take a stopped station: its owner; or, when nobody owns it (the teacher released it
        from this person), what keeps her from it."""
        group = self['group']
        if self.lease.owners.owner(group) is not None:
            return f'only its owner ({self.owner()}) can take it again, or an admin release it: press "Claim a ' \
                   'robot" for your own'
        why = self.lease._walk_in_refusal(group, self.key) or 'press "Claim a robot" for one'
        return f'nobody owns {group} now; {why}'

    def holder(self) -> str:
        return who(self.lease.holders[self['group']])

    def elsewhere(self) -> str:
        return self.lease.elsewhere(self['group'], self.key)

    def settler(self) -> str:
        return self.lease.settling[self['group']][1]

    def way_out(self) -> str:
        return self.lease._way_out(self.session, self['group'])

    def released(self) -> str:
        return self.lease._released(self['group'])

    def ended(self) -> str:
        return self.lease.owners.walk_in_refusal(self['group'], self.key)


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

    def facts(self, group: str, key: str | None, session=None, *, moving: bool = True) -> LeaseFacts:
        """The group's lease as person ``key`` (and her client ``session``, if one asks) sees it."""
        holder, owner, settling = self.holders.get(group), self.owners.owner(group), self.settling.get(group)
        free = owner is None
        return LeaseFacts(
            holder=Holder.NONE if holder is None else Holder.SELF if holder is session
            else Holder.SAME_PERSON if person(holder) == key else Holder.OTHER,
            owner=Owning.FREE if free else Owning.MINE if owner.person == key else Owning.OTHERS,
            barred=free and self.owners.is_barred(group, key),
            ended=free and key is not None and self.owners.walk_in_refusal(group, key) is not None,
            halted=group in self.halted,
            elsewhere=self.elsewhere(group, key) is not None,
            settling=Holder.NONE if settling is None else Holder.SELF if settling[0] == key else Holder.OTHER,
            moving=moving)

    def _refusal(self, command: Command, answer: Verdict, group: str, session=None, key: str | None = None,
                 name: str = '', ns: str = '') -> str:
        """The words of a refusal (``WORDS``), naming who holds what."""
        words = WORDS.get((command, answer)) or SAID[answer]
        return words.format_map(_Said(self, group, session, key, name, ns))

    def require(self, session, name: str, type: str | None = None, msg: dict | None = None) -> Wait | None:
        """Grant a free lease to a commanding client of the station's owner (or of a station nobody
        owns); refuse everyone but the holder. Nobody moves a stopped robot until its owner takes it
        again; zero commands (a page stopping its program) pass without taking the lease. In a
        fleet a free lease waits for PostgreSQL's word: the answer is then a ``Wait`` (settle.py).
        msg: the command (None: a moving one)."""
        if not self.is_command(name, type):   # the table's first row: a name that is no command passes
            return None
        group = self.group(name)
        if self.holders.get(group) is session:   # the holder's own: the table passes it whatever else holds
            return None                          # (tests/rules/test_lease_table.py), so nothing is looked up
        key, gateway = person(session), is_gateway(session)   # the gateway's zeros pass, whatever their type
        moving = msg is None or (type not in self.types and not gateway) or moving_command(msg)
        answer = self.grants.verdict(session, Command.DRIVE, self.facts(group, key, session, moving=moving))
        if answer.refused:
            raise ProtocolError(self._refusal(Command.DRIVE, answer, group, session, key, name))
        if answer is Verdict.WAIT:       # someone here is asking PostgreSQL for it: hers wait with it
            return self.settling[group][2]
        if answer is Verdict.QUIET:      # another page or run of the same person: her robot, without a word
            self._grant(group, session, quiet=True)
        elif answer is Verdict.GRANT:
            return self._grant_settled(group, session)
        return None

    def _walk_in_refusal(self, group: str, key: str) -> str | None:
        """Why person ``key`` may not take a station nobody owns: the teacher released it from her,
        someone else's booked slot is on, or hers there just ended (rules.stations); None: she may."""
        if self.owners.is_barred(group, key):
            return self._released(group)
        return self.owners.walk_in_refusal(group, key)

    def _way_out(self, session, group: str) -> str:
        """What resolves a refusal because someone else holds group's lease, for this client."""
        if self.grants.overrides(session):
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
        if not self.is_command(topic, type):   # the table's first row
            return None
        group = self.group(topic)   # (the table's answer to a playback is the same whoever starts it)
        answer = self.grants.verdict(None, Command.PLAY, self.facts(group, key))
        return self._refusal(Command.PLAY, answer, group, key=key) if answer.refused else None

    def publish_hook(self, session, pub, msg, issued=None):
        if pub.topic == CONTROL_TOPIC:
            return self._command(session, str(msg.get('data', '')).split())
        if not self.is_command(pub.topic, pub.type):   # a station's other topics: its holder's (stationnames)
            why = self.names.refusal(session, pub.topic)
            if why is not None:
                raise ProtocolError(why)
            return msg
        return self.require(session, pub.topic, pub.type, msg) or msg

    def run_refusal(self, key: str, role: str | None, ns: str) -> str | None:
        """Why a robot-side run of person ``key`` (starter's ``role``) could not drive namespace
        ``ns``, or None when it may (it then takes the lease, from its person's page quietly)."""
        group = self.group_of_namespace(ns)
        answer = self.grants.verdict(role, Command.RUN, self.facts(group, key))
        return self._refusal(Command.RUN, answer, group, key=key, ns=ns) if answer.refused else None

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
        if verb == 'release' and len(words) == 1:   # all of the client's: nothing to decide
            for group in [g for g, h in self.holders.items() if h is session]:
                self._grant(group, None)
            return None
        group = self.group_of_namespace(words[1]) if len(words) == 2 else ROOT
        command, key = Command(verb), person(session)
        answer = self.grants.verdict(session, command, self.facts(group, key, session))
        if answer.refused:
            raise ProtocolError(self._refusal(command, answer, group, session, key))
        holder = self.holders.get(group)
        if answer is Verdict.HALT:
            self.stopped[group] = round(time.time(), 3)
            if holder is not None:
                self._grant(group, None, by=session, why='stopped the robot and freed')
            self._halt(group, who(session))   # sticks until the owner's "take" or an admin's "release"
            self.stops.stop_group(group, self.group)
            self._announce()
            if self.fleet is not None and not self.fleet.confirmed():
                session.status('warning', f'{group} is stopped through this gateway; {self.fleet.why_unconfirmed()}, '
                                          'so the other gateways learn of the Stop when it is back')
        elif answer is Verdict.FREE:
            self._grant(group, None)
        elif answer is Verdict.FREE_BY:
            if holder is not None:
                self._grant(group, None, by=session, why='released')
            self._unhalt(group, end=who(session))   # and whoever drives it through another gateway
            self._announce()
        elif answer is Verdict.GRANT:
            if command is Command.TAKE:
                self._unhalt(group)
            return self._grant_settled(group, session)
        elif answer in (Verdict.KEEP, Verdict.SHARE, Verdict.TAKE_OVER):
            self._unhalt(group)
            if answer is Verdict.KEEP:
                self._announce()
            elif answer is Verdict.SHARE:   # her run, or another tab of hers: quietly
                self._grant(group, session)
                if session.attrs.get('run') is not None and holder.attrs.get('run') is None:
                    self.lent[group] = holder
            else:   # an admin's (or anyone's with --auth off) takeover: hers, whatever the others hold
                self._grant(group, session, by=session)
        return None

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
