"""The walk-in queue (with ``--booking``): when every station is taken, people wait in line and
are seated, in order, at the next station that frees (a slot ends with none after it, its owner
or the teacher releases it, a claim lapses).

A place in line is a person's (rules.stations.person), kept in memory: walk-ins are of the
moment. In a fleet (store.fleet) the line is one for every gateway: a place in it is a row (with
when she joined: the line's order, and the gateway she joined through), and each gateway seats
only the people who joined through it, when they come first: an earlier person in line is her own
gateway's to seat. A gateway started later, or one that could not hear for a while, reads the line. Someone who has no page connected for ``grace`` seconds leaves the line. While the
line is not empty, ``/fleet/claim`` does not hand a free station to someone not in it (it
would jump the line); ``Stations`` asks ``first_in_line``. The estimated wait of place k is
when the k-th station frees by what the gateway knows: a booked slot's end (and the bookings
right after it), now for a free one; a walk-in's claim has no known end, so past the stations
with known ends the estimate is None ("unknown").
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

GAP = 1.0   # s between two bookings that still counts as back to back


@dataclass
class Waiting:
    person: str
    name: str
    since: float = field(default_factory=time.time)
    seen: float = field(default_factory=time.monotonic)
    here: bool = True       # joined through this gateway (in a fleet, the others' are mirrored)


class Queue:
    def __init__(self, timetable, grace: float = 60.0, *, fleet=None):
        """fleet: store.fleet.Fleet, the line shared (rules.fleet)."""
        self.timetable, self.grace, self.fleet = timetable, grace, fleet
        self.line: list[Waiting] = []
        self.seated: dict[str, tuple[str, float]] = {}   # person -> (station, when), told once asked

    def place(self, key: str) -> int | None:
        return next((i + 1 for i, w in enumerate(self.line) if w.person == key), None)

    def first_in_line(self) -> str | None:
        return self.line[0].person if self.line else None

    def join(self, key: str, name: str) -> None:
        self.seated.pop(key, None)
        if self.place(key) is None:
            w = Waiting(key, name)
            self.line.append(w)
            if self.fleet is not None:
                self.fleet.put('queue', key, {'name': name, 'since': w.since})

    def leave(self, key: str) -> bool:
        before = len(self.line)
        self.line = [w for w in self.line if w.person != key]
        left = len(self.line) != before
        if self.fleet is not None and (left or ('queue', key) in self.fleet.values):
            self.fleet.remove('queue', key)
        return left

    def mirror(self, key: str, old: dict | None, new: dict | None) -> None:
        """The line's row of person ``key`` changed through another gateway: she joined there (in
        order of joining) or left."""
        self.line = [w for w in self.line if w.person != key]
        if new is not None:
            here = self.fleet is not None and new.get('gateway') == self.fleet.id
            self.line.append(Waiting(key, new.get('name', key), new.get('since', time.time()), here=here))
            self.line.sort(key=lambda w: w.since)

    def status(self, key: str, stations) -> dict:
        seated = self.seated.get(key)
        place = self.place(key)
        return {'place': place, 'queued': len(self.line), 'seated': seated[0] if seated else None,
                'wait': self.wait(place, stations) if place is not None else None,
                'line': [w.name for w in self.line]}

    def free_times(self, stations) -> list[float]:
        """When each station frees, for those where the gateway knows (sorted, epoch s)."""
        now = self.timetable.now()
        times = []
        for ns in stations.stations():
            booking = self.timetable.current(ns, now)
            owner = stations.owner(ns)
            if booking is None and owner is not None:
                continue        # a walk-in's claim: no known end
            end = now if booking is None else booking.end
            while (after := self.timetable.next(ns, end - GAP)) is not None and after.start <= end + GAP:
                end = after.end     # bookings back to back
            times.append(end)
        return sorted(times)

    def wait(self, place: int, stations) -> float | None:
        times = self.free_times(stations)
        if place > len(times):
            return None
        return max(0.0, round(times[place - 1] - self.timetable.now(), 1))

    def serve(self, stations, present: set[str]) -> list[tuple[str, str]]:
        """Seat people in line at free stations, in order; (person, station) of each seated.
        People with no page connected for ``grace`` seconds leave the line first."""
        now = time.monotonic()
        for w in [w for w in self.line if w.here]:   # another gateway's waiters are present there
            if w.person in present:
                w.seen = now
            elif now - w.seen > self.grace:
                self.leave(w.person)
        done = []
        for w in list(self.line):
            if not w.here:
                break           # she is first: her gateway seats her, then the line moves on here
            ns = stations.free_for(w.person)
            if ns is None:
                continue
            self.leave(w.person)
            self.seated[w.person] = (ns, time.time())
            done.append((w.person, w.name, ns))
        return done
