"""A live exercise attempt's station is the attempter's, and its robot moves only by being driven.

``lab.checker`` checks an attempt's goal on the station's own topics; what it may trust is
decided here, as the rules decide every other access (``live()``: the attempts going now, each with
``station``, ``person``, ``name``, ``kept`` (the pose and scan topics its goal reads), ``allow`` and
``refuse`` (an exercise's own service names or globs, absolute)). Tried as a class would: a student
passed in a second by teleporting her turtle into the goal, another failed her attempt by
teleporting it into the wall, and a third ended it by starting one on the same station. So:

- ``keeper`` (of ``rules.access``): during an attempt, the services and actions of its station that
  move the robot without driving it (``stationnames.MOVERS``: teleport, reset, spawn, kill, ... and
  any the exercise ``refuse``\\ s; not those it ``allow``\\ s) are refused to everyone, the teacher too
  (she may stop the attempt first); its station's other services are the attempter's and the admins'.
- ``publish_hook`` (first at the publish door): the pose and scan it reads are the robot's alone,
  and the station's topics are the attempter's (her pages and runs) and the admins'; the gateway's
  own stops pass.
- ``start_refusal``: an attempt is started only on a station its person could drive (the lease's
  ``run_refusal``; without the lease, not a station another person owns), not over another person's
  live attempt, and within the per-person caps (``AttemptCaps``: a rate and a daily count; 200
  starts in 14 s had written 200 recordings), admins excepted; a ``Refusal`` with its status.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from fnmatch import fnmatchcase

from protocol.errors import ProtocolError

from .access import Action, Area, allowed, is_gateway, owns, person_of, role_of
from .errors import Refusal
from .stationnames import moves_robot

GOALS = frozenset({'call', 'send_goal'})


@dataclass(frozen=True)
class AttemptCaps:
    per_minute: int = 6        # attempts one person may start in a minute
    per_day: int = 120         # and in a day


class AttemptRefused(Refusal):
    """An attempt that may not start: 409 (the station is someone else's) or 429 (past a cap)."""


def in_station(name: str, station: str) -> bool:
    return not station or name.startswith(station + '/')


def _matches(name: str, globs) -> bool:
    return any(fnmatchcase(name, g) for g in globs)


class AttemptRule:
    def __init__(self, live: Callable[[], Iterable], *, lease=None, stations=None, caps: AttemptCaps = AttemptCaps(),
                 clock: Callable[[], float] = time.monotonic):
        self.live, self.lease, self.stations, self.caps, self.clock = live, lease, stations, caps, clock
        self.starts: dict[str, deque] = {}    # person -> when their attempts of the last day started

    def keeper(self, who, action: str, name: str) -> str | None:
        if action not in GOALS:
            return None
        for a in self.live():
            if not in_station(name, a.station) or _matches(name, a.allow):
                continue
            if moves_robot(name) or _matches(name, a.refuse):
                return (f'{name} moves the robot without driving it: refused during the live exercise attempt on '
                        f'{a.station or "/"} (its goal is checked on the robot as it is driven)')
            if a.station and a.person and not owns(who, person_of(who) == a.person):
                return f'{name}: {a.station} is in {a.name}\'s live exercise attempt; it is theirs until it ends'
        return None

    def publish_hook(self, sender, pub, msg, issued=None):
        if is_gateway(sender):
            return msg
        for a in self.live():
            if pub.topic in a.kept:
                raise ProtocolError(f'{pub.topic} is read by a live exercise attempt on {a.station or "/"}: its goal '
                                    'is checked on the robot\'s own messages, not on a client\'s')
            if (a.station and a.person and in_station(pub.topic, a.station)
                    and not owns(sender, person_of(sender) == a.person)):
                raise ProtocolError(f'{pub.topic}: {a.station} is in {a.name}\'s live exercise attempt; it is theirs '
                                    'until it ends')
        return msg

    def start_refusal(self, who, person: str, station: str) -> None:
        """Raise AttemptRefused when ``who`` (person ``person``) may not start an attempt on ``station``."""
        role = role_of(who)
        lease = self.lease
        why = lease.run_refusal(person, role, station) if lease is not None else None
        if why is None and lease is None and self.stations is not None and station in self.stations.stations():
            owner = self.stations.owner(station)
            if owner is not None and owner.person != person and not allowed(who, Action.EXEMPT, Area.STATIONS):
                why = f'{station} is {owner.name}\'s station; claim a free robot, or ask the teacher'
        if why is not None:
            raise AttemptRefused(409, why)
        for a in self.live():
            if a.station == station and a.person != person:
                raise AttemptRefused(409, f'{a.name}\'s attempt is live on {station or "/"}; it ends at its goal or '
                                          'its time limit, or when the teacher stops it')
        if allowed(who, Action.EXEMPT, Area.ATTEMPTS) or not person:   # a signed-in admin: no cap
            return
        now = self.clock()
        starts = self.starts.setdefault(person, deque())
        while starts and starts[0] < now - 86400:
            starts.popleft()
        name = getattr(who, 'name', None) or person
        if len(starts) >= self.caps.per_day:
            raise AttemptRefused(429, f'{name} started {len(starts)} attempts today, the most one person may; '
                                      'ask the teacher')
        recent = [t for t in starts if t > now - 60]
        if len(recent) >= self.caps.per_minute:
            wait = max(1, round(recent[0] + 60 - now))
            raise AttemptRefused(429, f'{name} started {len(recent)} attempts in the last minute, the most one '
                                      f'person may: try again in {wait} s')

    def started(self, person: str) -> None:
        """An attempt of ``person`` began (counted against the caps)."""
        if person:
            self.starts.setdefault(person, deque()).append(self.clock())
