"""Robot stations and who owns them: a station belongs to a person, not to a tab.

Stations are the top namespaces of nodes that take a velocity topic inside them (the sim's
``--fleet`` stations ``/s01`` ..., or ``/robot1``, ``/robot2`` of a real multi-robot graph); the
driver lease keeps one lease per station. A *person* is who a client is: with ``--auth`` the
signed-in name; without it the browser's id (the cookie ``rosgate_browser``, a random id the pages
keep in the browser and send with every request); a client with neither (a script) is a person
of its own while it stays connected. A robot-side run acts for the person who started it.

While there are stations the gateway answers (std_srvs, knowing who calls):

- ``/fleet/claim`` (Trigger): your station; else the lowest one nobody owns, drives or watches;
  ``success`` false with the reason when none is free (a page then drives nothing);
- ``/sNN/fleet/claim`` (Trigger): that station, if nobody else owns it (one station per person:
  your previous one is given back);
- ``/sNN/fleet/release`` (Trigger): give it back (its owner, or an admin: the teacher's Release;
  the owner's clients are told);
- ``/fleet/release_all`` (Empty): every station free (an admin, with ``--auth``).

A claim holds for the lesson, through reloads, closed tabs and sleeping tablets, until its owner
or the teacher releases it or none of the owner's clients has been connected for ``--claim-idle``
seconds (an hour by default); a script's claim lapses ``--claim-grace`` seconds after it leaves.
Who owns what is announced, latched, on /rosgate/stations as JSON: {"stations": [...],
"owners": {ns: {"name", "since"}}, "released": {ns: {"by", "at"}}} ("released": the last time
someone other than its owner gave a station back).
"""

from __future__ import annotations

import asyncio
import json
import re
import time
from dataclasses import dataclass

from protocol.errors import ProtocolError

from ..backends.base import QoS

STATIONS_TOPIC = '/rosgate/stations'
STRING = 'std_msgs/msg/String'
TRIGGER, EMPTY = 'std_srvs/srv/Trigger', 'std_srvs/srv/Empty'
CLAIM, RELEASE_ALL = '/fleet/claim', '/fleet/release_all'
BROWSER_COOKIE = 'rosgate_browser'
BROWSER_ID = re.compile(r'[A-Za-z0-9_-]{8,64}')
STATIONS_TTL = 1.0        # s between looks at the graph for stations
CHECK_PERIOD = 1.0        # s between looks for lapsed claims and new stations
CLAIM_IDLE = 3600.0       # s a person's station stays theirs with none of their clients connected
CLAIM_GRACE = 60.0        # s a script's station stays its own after it leaves
# topics of a station that watching does not count as using it (the teacher's view watches them)
WATCHED = ('world/markers', 'rosgate/program')


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


class Stations:
    def __init__(self, gateway, *, types: frozenset[str], idle: float = CLAIM_IDLE,
                 grace: float = CLAIM_GRACE, admin_role: str | None = None):
        """admin_role: who may release others' stations (None: anyone, as without --auth)."""
        self.gateway, self.types, self.idle, self.grace, self.admin_role = gateway, types, idle, grace, admin_role
        self.owners: dict[str, Owner] = {}
        self.released: dict[str, dict] = {}
        self._stations: tuple[str, ...] = ()
        self._stations_at = -float('inf')
        self._served: set[str] = set()
        self._topic = gateway.own_topic(STATIONS_TOPIC, STRING, QoS(depth=1, transient_local=True))
        self._announced = None
        self._timer: asyncio.TimerHandle | None = None
        self._check()

    # --- stations -------------------------------------------------------------------------------

    def stations(self) -> tuple[str, ...]:
        now = time.monotonic()
        if now - self._stations_at > STATIONS_TTL:
            self._stations, self._stations_at = find_stations(self.gateway.backend, self.types), now
        return self._stations

    def owner(self, station: str) -> Owner | None:
        return self.owners.get(station)

    def is_owner(self, session, station: str) -> bool:
        o = self.owners.get(station)
        return o is not None and o.person == person(session)

    def in_use(self, station: str, key: str) -> bool:
        """Whether a client of another person publishes on one of the station's topics, or
        subscribes to one that is not only watched."""
        gw, prefix = self.gateway, station + '/'
        ids: set[int] = set()
        for topic, pub in gw.publishers.items():
            if topic.startswith(prefix):
                ids |= pub.clients
        for topic, fan in gw.fanouts.items():
            if topic.startswith(prefix) and topic[len(prefix):] not in WATCHED:
                ids |= set(fan.subscribers)
        return any(person(s) != key for i in ids if (s := gw.sessions.get(i)) is not None)

    # --- claims ---------------------------------------------------------------------------------

    def claim(self, session, station: str | None = None) -> dict:
        """The answer of /fleet/claim (station None) or /sNN/fleet/claim."""
        key = person(session)
        mine = next((ns for ns, o in self.owners.items() if o.person == key), None)
        if station is None:
            if mine is not None:
                return self._own(session, mine)
            lease = getattr(self.gateway.policy, 'lease', None)
            for ns in self.stations():
                held = lease.holders.get(ns) if lease is not None else None
                if ns not in self.owners and not self.in_use(ns, key) and (held is None or person(held) == key):
                    return self._own(session, ns)
            n = len(self.stations())
            return {'success': False, 'message': f'all {n} stations are taken; ask the teacher to release one'}
        o = self.owners.get(station)
        if o is not None and o.person != key:
            return {'success': False, 'message': f'{station} is {o.name}\'s station; ask the teacher, or '
                                                 'claim a free one'}
        if mine is not None and mine != station:
            del self.owners[mine]
        return self._own(session, station)

    def _own(self, session, station: str) -> dict:
        o = self.owners.get(station)
        name = session.attrs.get('name') or f'client {session.id}'
        if o is None:
            self.owners[station] = Owner(person(session), name, round(time.time(), 3), time.monotonic())
            self.released.pop(station, None)
        else:
            o.name, o.seen = name, time.monotonic()
        self._announce()
        return {'success': True, 'message': station}

    def release(self, session, station: str) -> dict:
        o = self.owners.get(station)
        if o is None:
            return {'success': False, 'message': f'{station} was not claimed'}
        if o.person != person(session):
            if not self._may_release(session):
                raise ProtocolError(f'{station} is {o.name}\'s station; only they or an admin can release it')
            by = session.attrs.get('name') or f'client {session.id}'
            self.released[station] = {'by': by, 'at': round(time.time(), 3)}
            for s in self._clients_of(o.person):
                s.status('warning', f'{by} released {station}: it is no longer your station')
        del self.owners[station]
        self._announce()
        return {'success': True, 'message': station}

    def release_all(self, session) -> dict:
        if not self._may_release(session):
            raise ProtocolError('only an admin can release every station')
        for station in list(self.owners):
            self.release(session, station)
        return {}

    def _may_release(self, session) -> bool:
        return self.admin_role is None or session.attrs.get('role') == self.admin_role

    def _clients_of(self, key: str) -> list:
        return [s for s in self.gateway.sessions.values() if person(s) == key]

    # --- the services, the announcement and lapsed claims ---------------------------------------

    def _serve(self) -> None:
        stations = self.stations()
        wanted = {CLAIM: (TRIGGER, lambda s, req: self.claim(s)),
                  RELEASE_ALL: (EMPTY, lambda s, req: self.release_all(s))} if stations else {}
        for ns in stations:
            wanted[f'{ns}/fleet/claim'] = (TRIGGER, lambda s, req, ns=ns: self.claim(s, ns))
            wanted[f'{ns}/fleet/release'] = (TRIGGER, lambda s, req, ns=ns: self.release(s, ns))
        if set(wanted) == self._served:
            return
        for name in self._served - set(wanted):
            self.gateway.drop_own_service(name)
        for name, (type, answer) in wanted.items():
            self.gateway.own_service(name, type, answer)
        self._served = set(wanted)

    def _announce(self) -> None:
        text = json.dumps({'stations': list(self.stations()),
                           'owners': {ns: {'name': o.name, 'since': o.since} for ns, o in sorted(self.owners.items())},
                           'released': self.released})
        if text != self._announced:
            self._announced = text
            self._topic.publish({'data': text})

    def _check(self) -> None:
        """Every CHECK_PERIOD: new stations served and announced; claims of the absent lapse."""
        now = time.monotonic()
        present = {person(s) for s in self.gateway.sessions.values()}
        for ns, o in list(self.owners.items()):
            if o.person in present:
                o.seen = now
            elif now - o.seen > (self.idle if lasting(o.person) else self.grace):
                del self.owners[ns]
        self._stations_at = -float('inf')
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
