"""Robot stations and who owns them: a station belongs to a person, not to a tab.

Stations are the top namespaces of nodes that take a velocity topic inside them (the sim's
``--fleet`` stations ``/s01`` ..., or ``/robot1``, ``/robot2`` of a real multi-robot graph); the
driver lease keeps one lease per station. A *person* is who a client is: with ``--auth`` the
signed-in name; without it the browser's id (the cookie ``rosgate_browser``, a random id the pages
keep in the browser and send with every request); a client with neither (a script) is a person
of its own while it stays connected. A robot-side run acts for the person who started it.

While there are stations the gateway answers (std_srvs, knowing who calls):

- ``/fleet/claim`` (Trigger): your station (the one your booked slot is on, with ``--booking``);
  else the lowest one nobody owns, drives or has booked now; ``success`` false with the reason when
  none is free (a page then drives nothing). Watching is not claiming: a client that only
  subscribes to a station's topics (a projector page, a dashboard, a recorder) leaves it free;
- ``/sNN/fleet/claim`` (Trigger): that station, if nobody else owns it (one station per person:
  your previous one is given back);
- ``/sNN/fleet/release`` (Trigger): give it back (its owner, or an admin: the teacher's Release,
  which also frees its driver lease and its stop in the same step; the owner's clients are told);
- ``/fleet/release_all`` (Empty): every station free (an admin, with ``--auth``).

The teacher's Release sticks as her Stop does: the person it was taken from is *barred* from that
station (no command, no lease, no take of hers moves it) until she claims a station again. Without
the bar a page of hers still open on it (a teleop page whose joystick was held) took the free
station back on its next command, and the release was undone within a second.

A claim holds for the lesson, through reloads, closed tabs and sleeping tablets, until its owner
or the teacher releases it or none of the owner's clients has been connected for ``--claim-idle``
seconds (an hour by default); a script's claim lapses ``--claim-grace`` seconds after it leaves.
With ``--booking`` a booked slot seats its booker on the station for the slot (``seat``) whatever
the claims, and ends with it (``unseat``); a walk-in's claim of an unbooked station holds until
the next booking begins. Who owns what is announced, latched, on /rosgate/stations as JSON:
{"stations": [...], "owners": {ns: {"name", "since", "until"}}, "released": {ns: {"by", "at"}},
"booked": {ns: {"name", "start", "end"}}, "next": {ns: {"name", "start", "end"}}} ("released": the
last time someone other than its owner gave a station back; "until": a booked slot's end;
"booked"/"next": the slot on now and the next one, and "queue": the names of walk-ins waiting,
in order, with --booking; rules.queue seats them at stations as they free).
"""

from __future__ import annotations

import asyncio
import json
import re
import time
from collections.abc import Callable
from dataclasses import dataclass

from protocol.errors import ProtocolError

from ..backends.base import QoS
from .hooks import Hook
from .leasetable import Command, LeaseFacts
from .ports import Announcer, Graph, LeaseView, Parties
from ..settings import StationSettings
from ..store.fleet import Unreachable

STATIONS_TOPIC = '/rosgate/stations'
STRING = 'std_msgs/msg/String'
TRIGGER, EMPTY = 'std_srvs/srv/Trigger', 'std_srvs/srv/Empty'
CLAIM, RELEASE_ALL = '/fleet/claim', '/fleet/release_all'
BROWSER_COOKIE = 'rosgate_browser'
BROWSER_ID = re.compile(r'[A-Za-z0-9_-]{8,64}')
STATIONS_TTL = 1.0        # s between looks at the graph for stations
CHECK_PERIOD = 1.0        # s between looks for lapsed claims and new stations
CLAIM_IDLE = StationSettings.claim_idle     # s a person's station stays theirs with none of their clients connected
CLAIM_GRACE = StationSettings.claim_grace   # s a script's station stays its own after it leaves


def _clock(at: float) -> str:
    return time.strftime('%H:%M:%S', time.localtime(at))


def find_stations(backend: Graph, types: frozenset[str]) -> tuple[str, ...]:
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


def person(session) -> str:
    """Who a client or sender is, for owning a station (see the module docstring)."""
    return session.attrs.get('person') or f'client {session.id}'


def person_of(identity, cookies) -> str | None:
    """The person of a request: the signed-in name (identity), else the browser's id (cookies:
    a tornado request's), else None."""
    if identity is not None:
        return f'user {identity.owner}'
    cookie = cookies.get(BROWSER_COOKIE)
    value = cookie.value if cookie is not None else ''
    return f'browser {value}' if BROWSER_ID.fullmatch(value) else None


def lasting(key: str) -> bool:
    """Whether a person can come back (a name or a browser), rather than one connection."""
    return not key.startswith('client ')


@dataclass
class Owner:
    person: str
    name: str
    since: float
    seen: float      # monotonic time one of the owner's clients was last connected
    until: float | None = None   # a booked slot's end (epoch s): the seat holds till then, present or not


class Stations(Hook):
    def __init__(self, *, announce: Announcer, graph: Graph, parties: Parties,
                 lease: Callable[[], LeaseView | None] = lambda: None, types: frozenset[str],
                 idle: float = CLAIM_IDLE, grace: float = CLAIM_GRACE, grants=None, timetable=None, queue=None,
                 fleet=None):
        """announce: /rosgate/stations and the claim services; graph: where stations are found;
        parties: who is connected and what they advertise; lease: () -> the driver lease (built after
        the stations, which it asks; None: no --exclusive-control);
        grants: who may release others' stations (``rules.access.StationGrants``; None: anyone, as without --auth);
        timetable: the bookings (rules.bookings.Timetable) and queue: the walk-ins' line
        (rules.queue.Queue), with --booking; fleet: store.fleet.Fleet, claims made through other
        gateways (rules.fleet)."""
        self.announce, self.graph, self.parties, self._lease = announce, graph, parties, lease
        self.types, self.idle, self.grace, self.grants = types, idle, grace, grants
        self.timetable, self.queue = timetable, queue
        self.owners: dict[str, Owner] = {}
        self.released: dict[str, dict] = {}
        self.barred: dict[str, str] = {}      # station -> the person the teacher released it from
        self.fleet = fleet
        self._stations: tuple[str, ...] = ()
        self._stations_at = -float('inf')
        self._served: set[str] = set()
        self._topic = announce.own_topic(STATIONS_TOPIC, STRING, QoS(depth=1, transient_local=True))
        self._announced = None
        self._timer: asyncio.TimerHandle | None = None
        self._check()

    # --- stations -------------------------------------------------------------------------------

    def stations(self) -> tuple[str, ...]:
        now = time.monotonic()
        if now - self._stations_at > STATIONS_TTL:
            self._stations, self._stations_at = find_stations(self.graph, self.types), now
        return self._stations

    def owner(self, station: str) -> Owner | None:
        """Who owns the station: claimed here, or through another gateway of the fleet (a dict lookup;
        not a booker whose slot there ended here: another gateway's clock may end it a moment later)."""
        o = self.owners.get(station)
        if o is None and self.fleet is not None:
            held = self.fleet.held('claim', station)
            if held is not None and (self.timetable is None
                                     or self.timetable.walk_in_refusal(station, held.person) is None):
                return Owner(held.person, held.who, 0.0, time.monotonic())
        return o

    def is_owner(self, session, station: str) -> bool:
        o = self.owner(station)
        return o is not None and o.person == person(session)

    def is_barred(self, station: str, key: str) -> bool:
        """Whether person ``key`` lost ``station`` to the teacher's Release and has not claimed since."""
        return self.barred.get(station) == key

    def in_use(self, station: str, key: str) -> bool:
        """Whether a client of another person advertises one of the station's topics (drives it,
        or is about to). Subscribers do not count: watching is not claiming."""
        parties, prefix = self.parties, station + '/'
        ids: set[int] = set()
        for topic, pub in parties.publishers.items():
            if topic.startswith(prefix):
                ids |= pub.clients
        return any(person(s) != key for i in ids if (s := parties.sessions.get(i)) is not None)

    def free_for(self, key: str) -> str | None:
        """The lowest station person ``key`` may walk into now: nobody owns it, has it booked, or
        drives it (but them), and no slot of theirs just ended there."""
        lease = self._lease()
        for ns in self.stations():
            held = lease.holders.get(ns) if lease is not None else None
            if (self.owner(ns) is None and not self.in_use(ns, key) and (held is None or person(held) == key)
                    and (lease is None or lease.elsewhere(ns, key) is None)
                    and self.booked(ns) is None and self.walk_in_refusal(ns, key) is None):
                return ns
        return None

    def walk_in_refusal(self, station: str, key: str) -> str | None:
        """Why person ``key`` may not take a station nobody owns now (a slot of theirs just ended
        there, rules.bookings, or someone else's slot is on though nobody holds the seat: the
        teacher released it); None: they may."""
        if self.timetable is None:
            return None
        slot = self.timetable.current(station)
        if slot is not None and slot.person != key:
            return f'{station} is booked by {slot.name} until {_clock(slot.end)}; claim a free one, or book a slot'
        return self.timetable.walk_in_refusal(station, key)

    def booked(self, station: str):
        """The booking whose slot is on now at the station (None: none, or no --booking)."""
        return self.timetable.current(station) if self.timetable is not None else None

    # --- claims ---------------------------------------------------------------------------------

    def claim(self, session, station: str | None = None) -> dict:
        """The answer of /fleet/claim (station None) or /sNN/fleet/claim."""
        key = person(session)
        mine = next((ns for ns, o in self.owners.items() if o.person == key), None)
        if station is None:
            if mine is not None:
                return self._own(session, mine)
            first = self.queue.first_in_line() if self.queue is not None else None
            if first is not None and first != key:
                n = len(self.queue.line)
                return {'success': False, 'message': f'{n} {"person is" if n == 1 else "people are"} waiting for a '
                                                     'station; join the queue (Booking, then Queue)'}
            ns = self.free_for(key)
            if ns is not None:
                if self.queue is not None:
                    self.queue.leave(key)
                return self._own(session, ns)
            n = len(self.stations())
            also = '; or join the queue (Booking, then Queue)' if self.queue is not None else ''
            return {'success': False, 'message': f'all {n} stations are taken; ask the teacher to release one{also}'}
        o = self.owner(station)
        if o is not None and o.person != key:
            held = f' until {_clock(o.until)} (booked)' if o.until is not None else ''
            return {'success': False, 'message': f'{station} is {o.name}\'s station{held}; ask the teacher, or '
                                                 'claim a free one'}
        why = self.walk_in_refusal(station, key) if o is None else None
        if why is not None:
            return {'success': False, 'message': why}
        if mine is not None and mine != station:
            del self.owners[mine]
        return self._own(session, station)

    def _claimed(self, session, station: str | None = None):
        """The claim services' answer: at once alone, PostgreSQL's word in a fleet (awaitable)."""
        return self.claim(session, station) if self.fleet is None else self.claim_in_fleet(session, station)

    async def claim_in_fleet(self, session, station: str | None = None) -> dict:
        """``claim``, then PostgreSQL's word on it: another gateway may have given the station to
        someone else a moment ago (its event not heard here yet). Then the claim is refused, naming
        the holder, and nothing of it stays."""
        answer = self.claim(session, station)
        ns = answer['message']
        o = self.owners.get(ns) if answer['success'] else None
        if o is None:
            return answer
        try:
            holder = await self.fleet.take('claim', ns, o.person, o.name)
        except Unreachable as e:
            holder, why = None, f'{e}, so it cannot confirm your claim of {ns}; try again in a moment'
        else:
            if holder is None:        # hers in PostgreSQL, which lifted any Release that barred her
                if self.owners.get(ns) is not o:     # (heard meanwhile, and undone here too)
                    self.owners[ns] = o
                for barred in [s for s, p in self.barred.items() if p == o.person or s == ns]:
                    del self.barred[barred]
                self._announce()
                return answer
            why = f'{ns} is {holder.who}\'s station (claimed through another gateway); ask the teacher, or ' \
                  'claim a free one'
        if self.owners.get(ns) is o:
            del self.owners[ns]
            self._announce()
        return {'success': False, 'message': why}

    def _own(self, session, station: str) -> dict:
        o = self.owners.get(station)
        name = session.attrs.get('name') or f'client {session.id}'
        if o is None:
            key = person(session)
            slot = self.booked(station)
            until = slot.end if slot is not None and slot.person == key else None
            self.owners[station] = Owner(key, name, round(time.time(), 3), time.monotonic(), until)
            self.released.pop(station, None)
            for ns in [ns for ns, p in self.barred.items() if p == key or ns == station]:
                self._unbar(ns)         # she claimed again: the teacher's Release is behind her
        else:
            o.name, o.seen = name, time.monotonic()
        self._announce()
        return {'success': True, 'message': station}

    def seat(self, station: str, key: str, name: str, until: float) -> list[str]:
        """A booked slot begins: the station is ``key``'s till ``until`` (a walk-in's claim ends,
        and the booker's claim of another station is given back: those are returned)."""
        given_back = [ns for ns, o in self.owners.items() if o.person == key and ns != station]
        for ns in given_back:
            del self.owners[ns]
        o = self.owners.get(station)
        if o is not None and o.person != key:
            for s in self._clients_of(o.person):
                s.status('warning', f'{station} is booked by {name} from now: it is no longer your station')
        self.owners[station] = Owner(key, name, round(time.time(), 3), time.monotonic(), until)
        self.released.pop(station, None)
        self._unbar(station)   # her booked slot: a Release of a walk-in before it is behind
        for s in self._clients_of(key):
            s.status('info', f'your booked slot on {station} began; it ends at {_clock(until)}')
        self._announce()
        return given_back

    def unseat(self, station: str, key: str, why: str) -> None:
        """A booked slot ended: the station is no longer its booker's."""
        o = self.owners.get(station)
        if o is not None and o.person == key:
            del self.owners[station]
            for s in self._clients_of(key):
                s.status('warning', f'{why}: it is no longer your station')
        self._announce()

    def refresh(self) -> None:
        self._announce()

    def release(self, session, station: str) -> dict:
        o = self.owner(station)
        if o is None:
            if self._may_release(session):
                self._free_lease(session, station)
            return {'success': False, 'message': f'{station} was not claimed'}
        if o.person != person(session):
            if not self._may_release(session):
                raise ProtocolError(f'{station} is {o.name}\'s station; only they or an admin can release it')
            by = session.attrs.get('name') or f'client {session.id}'
            self.released[station] = {'by': by, 'at': round(time.time(), 3)}
            self.barred[station] = o.person
            if self.fleet is not None:   # a row: her pages on every gateway are barred, her claim ends
                self.fleet.put('bar', station, {'person': o.person, **self.released[station]},
                               ends=[('claim', station)], why=f'{by} released {station}')
            for s in self._clients_of(o.person):
                s.status('warning', f'{by} released {station}: it is not your robot any more; press '
                                    '"Claim a robot" for one')
        if self.owners.pop(station, None) is None and self.fleet is not None and o.person == person(session):
            self.fleet.end('claim', station, f'{station} was given back')   # her claim, held through another gateway
        self._announce()                     # first: her pages learn it is not hers before it is free
        self._free_lease(session, station)   # (its driver through any gateway, too)
        return {'success': True, 'message': station}

    def release_all(self, session) -> dict:
        if not self._may_release(session):
            raise ProtocolError('only an admin can release every station')
        for station in self.stations():
            if self.owner(station) is not None:
                self.release(session, station)
            else:
                self._free_lease(session, station)
        return {}

    def _free_lease(self, session, station: str) -> None:
        """The station's driver lease and stop go with its claim, in the same step: a page of the
        old owner must not find it held by nobody and owned by nobody in between."""
        lease = self._lease()
        if lease is not None:
            lease.free(station, session)

    def _may_release(self, session) -> bool:
        """Another's station, or all of them (the lease's table: RELEASE_STATION)."""
        return self.grants is None or not self.grants.verdict(session, Command.RELEASE_STATION, LeaseFacts()).refused

    def _clients_of(self, key: str) -> list:
        return [s for s in self.parties.sessions.values() if person(s) == key]

    # --- the services, the announcement and lapsed claims ---------------------------------------

    def _serve(self) -> None:
        stations = self.stations()
        wanted = {CLAIM: (TRIGGER, lambda s, req: self._claimed(s)),
                  RELEASE_ALL: (EMPTY, lambda s, req: self.release_all(s))} if stations else {}
        for ns in stations:
            wanted[f'{ns}/fleet/claim'] = (TRIGGER, lambda s, req, ns=ns: self._claimed(s, ns))
            wanted[f'{ns}/fleet/release'] = (TRIGGER, lambda s, req, ns=ns: self.release(s, ns))
        if set(wanted) == self._served:
            return
        for name in self._served - set(wanted):
            self.announce.drop_own_service(name)
        for name, (type, answer) in wanted.items():
            self.announce.own_service(name, type, answer)
        self._served = set(wanted)

    def freed_elsewhere(self, station: str, by: str, key: str, barred: str | None) -> None:
        """A station given back through another gateway (its owner, or the teacher's Release)."""
        o = self.owners.get(station)
        if o is not None and o.person == key:
            del self.owners[station]
        if barred is not None:
            self.released[station] = {'by': by, 'at': round(time.time(), 3)}
            self.barred[station] = barred
            for s in self._clients_of(barred):
                s.status('warning', f'{by} released {station}: it is not your robot any more; press '
                                    '"Claim a robot" for one')
        self._announce()
        lease = self._lease()
        if lease is not None:
            lease.released_elsewhere(station, by)

    def lost_elsewhere(self, station: str, hold, why: str | None = None) -> None:
        """Our claim is gone from PostgreSQL: two gateways claimed one station at once and it gave
        it to the other one's (``hold``), or it was given back through another gateway (None)."""
        o = self.owners.pop(station, None)
        if o is not None:
            why = (f'{station} is {hold.who}\'s station (claimed through another gateway at the same moment)'
                   if hold is not None else why or f'{station} was given back through another gateway')
            for s in self._clients_of(o.person):
                s.status('warning', f'{why}; press "Claim a robot" for another')
        self._announce()

    def _unbar(self, station: str) -> None:
        if self.barred.pop(station, None) is not None and self.fleet is not None:
            self.fleet.remove('bar', station)

    def barred_elsewhere(self, station: str, old: dict | None, new: dict | None) -> None:
        """The teacher's Release of a person, through another gateway (its row): she is barred here
        too; or that bar ended (she claimed again)."""
        if new is None:
            if old is not None and self.barred.get(station) == old.get('person'):
                del self.barred[station]
            self._announce()
            return
        key = new.get('person')
        if self.barred.get(station) != key:
            self.freed_elsewhere(station, new.get('by', 'the teacher'), key, key)

    def _share(self) -> None:
        """This gateway's claims held in the fleet's table (no-op when unchanged), the given-back dropped."""
        for ns, o in self.owners.items():
            self.fleet.hold('claim', ns, o.person, o.name)
        for kind, ns in [k for k in self.fleet.mine if k[0] == 'claim' and k[1] not in self.owners]:
            self.fleet.drop(kind, ns)

    def _all_owners(self) -> dict[str, Owner]:
        """This gateway's claims and, in a fleet, the others' (so every page shows who has what)."""
        found = {ns: o for ns in self.stations() if (o := self.owner(ns)) is not None}
        return {**found, **self.owners}

    def _announce(self) -> None:
        if self.fleet is not None:
            self._share()
        info = {'stations': list(self.stations()),
                'owners': {ns: {'name': o.name, 'since': o.since, 'until': o.until}
                           for ns, o in sorted(self._all_owners().items())},
                'released': self.released}
        if self.timetable is not None:
            slot = lambda b: {'name': b.name, 'start': b.start, 'end': b.end}   # noqa: E731
            now = self.timetable.now()
            info['booked'] = {ns: slot(b) for ns in self.stations() if (b := self.timetable.current(ns, now))}
            info['next'] = {ns: slot(b) for ns in self.stations() if (b := self.timetable.next(ns, now))}
        if self.queue is not None:
            info['queue'] = [w.name for w in self.queue.line]
        text = json.dumps(info)
        if text != self._announced:
            self._announced = text
            self._topic.publish({'data': text})

    def _check(self) -> None:
        """Every CHECK_PERIOD: new stations served and announced; claims of the absent lapse."""
        now = time.monotonic()
        present = {person(s) for s in self.parties.sessions.values()}
        for ns, o in list(self.owners.items()):
            if o.person in present:
                o.seen = now
            elif o.until is not None:
                continue   # a booked seat: its slot's end unseats it (rules.bookings)
            elif now - o.seen > (self.idle if lasting(o.person) else self.grace):
                del self.owners[ns]
        self._stations_at = -float('inf')
        if self.queue is not None:
            for key, name, ns in self.queue.serve(self, present):
                self.owners[ns] = Owner(key, name, round(time.time(), 3), now)
                self.released.pop(ns, None)
                for s in self._clients_of(key):
                    s.status('info', f'{ns} is yours now (your turn in the queue): press "Claim a robot"')
        self._serve()
        self._announce()
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        self._timer = loop.call_later(CHECK_PERIOD, self._check)

    def on_shutdown(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
