"""Bookings (``--booking``): who may drive which station when, and the gateway's own clock ending
each slot.

A lab with a few real robots and many students shares them by slots booked ahead. A booking is
(station, person, start, end) in epoch seconds, kept in the one store (table ``bookings``), so it
survives a restart. ``Timetable`` holds them, checks a new one against the teacher's limits
(``--slot-minutes`` the longest slot, ``--booking-per-day`` / ``--booking-per-week`` slots one
person may book, ``--booking-ahead`` days) and answers what the rules ask: whose slot is on now,
when the next one begins, who may not walk in.

``Slots`` is the timer. At a slot's start the station becomes its booker's (``Stations.seat``):
anyone else's claim and driver lease end, the booker's first command takes the lease without
Take. At its end the gateway acts by itself, whatever the pages do (a sleeping laptop or a dead
link changes nothing): the lease is freed and every command left moving in the station is zeroed
through the same path as the teacher's Stop (``rules.stops``: clients, playbacks), the booker's
robot-side runs in the station end (hooks' ``on_slot_ended``), the ``--station-reset`` service is
called in the station's namespace, and the next booking takes over. Until the next booking, or
one slot length after hers, the booker may not walk back in (a slot cannot be stretched).

In a fleet of gateways on one PostgreSQL (``store.fleet``) a booking made through one is known to
the others at once (an event, then the timetable read again; and whenever the rows change, read
each second), two gateways booking one time are serialized by a transaction lock, and every
gateway seats and ends each slot on its own timer: a slot ends on time when the gateway it was
booked through has died, or while the database is away. The --station-reset call is made once per
slot's end: by the gateway that claims it first in the database (``Fleet.once``).

The timer sleeps until the next boundary (start or end of any booking), never more than
MAX_SLEEP: the wall clock decides, and a clock that jumps is caught at the next wake-up.
"""

from __future__ import annotations

import asyncio
import bisect
import datetime
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import sqlalchemy as sa

from ..settings import LabSettings
from ..store import METADATA
from ..auth import courses
from .errors import Refusal
from .hooks import Hook
from .ports import Caller, SlotEvents, TimetableEvents
from .stops import Stops

log = logging.getLogger('rosgate.bookings')
MAX_SLEEP = 5.0            # s the timer sleeps at most (catches a clock that jumped)
LATE = 0.002               # s past a boundary that still counts as "at" it
SLACK = 0.5               # s a slot may run over --slot-minutes (clients' rounding)
RESET_TIMEOUT = 5.0        # s the --station-reset service may take
RESET_TYPES = ('std_srvs/srv/Empty', 'std_srvs/srv/Trigger')

TABLE = sa.Table(
    'bookings', METADATA,
    sa.Column('id', sa.Integer, primary_key=True, autoincrement=True),
    sa.Column('station', sa.String(100), nullable=False),
    sa.Column('person', sa.String(200), nullable=False),
    sa.Column('name', sa.String(200), nullable=False),
    sa.Column('start_at', sa.Float, nullable=False),
    sa.Column('end_at', sa.Float, nullable=False),
    sa.Column('created_at', sa.Float, nullable=False),
    sa.Index('bookings_by_station', 'station', 'start_at'),
)


class BookingError(Refusal):
    """A booking refused: ``status`` is the HTTP status that says why (400, 403, 404, 409, 429)."""


@dataclass(frozen=True)
class BookingLimits:
    slot: float = LabSettings.slot_minutes * 60           # s, the longest slot (--slot-minutes)
    per_day: int = LabSettings.booking_per_day            # slots one person may book per calendar day (0: no limit)
    per_week: int = LabSettings.booking_per_week          # per ISO week (0: no limit)
    ahead: float = LabSettings.booking_ahead * 86400      # s ahead a slot may begin


@dataclass(eq=False)
class Booking:
    station: str
    person: str
    name: str
    start: float
    end: float
    id: int | None = None      # None until the store has written it
    created: float = field(default_factory=time.time)

    def json(self) -> dict:
        return {'id': self.id, 'station': self.station, 'name': self.name, 'owner': self.name, 'start': self.start,
                'end': self.end}

    def on(self, at: float) -> bool:
        return self.start <= at < self.end


def clock(at: float) -> str:
    return time.strftime('%H:%M:%S', time.localtime(at))


class Timetable:
    """Every booking not long past, in memory (sorted by start), written through to the store."""

    def __init__(self, store, limits: BookingLimits, now: Callable[[], float] = time.time, *,
                 events: TimetableEvents | None = None, fleet=None):
        """events: told of each change (``rules.hooks.Hooks``: Slots wakes up); fleet:
        store.fleet.Fleet, bookings made through other gateways (rules.fleet)."""
        self.store, self.limits, self.now = store, limits, now
        self.events, self.fleet = events, fleet
        self.bookings: list[Booking] = []
        self.ended: dict[str, tuple[str, float]] = {}       # station -> (its last booker, barred until)
        self.bookings = store.run_now(self._load)
        log.info('bookings: %d loaded from %s', len(self.bookings), store.url)

    def _load(self, c: sa.Connection) -> list[Booking]:
        since = self.now() - 8 * 86400.0   # the past that quotas still count
        rows = c.execute(sa.select(TABLE).where(TABLE.c.end_at > since).order_by(TABLE.c.start_at)).all()
        return [Booking(r.station, r.person, r.name, r.start_at, r.end_at, r.id, r.created_at) for r in rows]

    async def reload(self) -> None:
        """Another gateway of the fleet booked or removed a slot: the timetable read again, the
        same Booking kept for a booking already known (Slots compares them by identity)."""
        rows = await self.store.run(self._load)
        known = {b.id: b for b in self.bookings if b.id is not None}
        self.bookings = [known.get(b.id, b) for b in rows] + [b for b in self.bookings if b.id is None]
        self.bookings.sort(key=lambda b: b.start)
        self._changed()

    # --- questions the rules ask ------------------------------------------------------------------

    def walk_in_refusal(self, station: str, key: str) -> str | None:
        """Why person ``key`` may not claim or drive the station while nobody has it booked (her
        slot there just ended); None: they may."""
        ended = self.ended.get(station)
        if ended is not None and ended[0] == key and self.now() < ended[1]:
            return f'your slot on {station} has ended; book another, or walk in again after {clock(ended[1])}'
        return None

    def current(self, station: str, at: float | None = None) -> Booking | None:
        at = self.now() if at is None else at
        return next((b for b in self.bookings if b.station == station and b.on(at)), None)

    def next(self, station: str, at: float | None = None) -> Booking | None:
        """The first booking of the station that begins after ``at``."""
        at = self.now() if at is None else at
        return next((b for b in self.bookings if b.station == station and b.start > at), None)

    def of(self, person: str) -> list[Booking]:
        return [b for b in self.bookings if b.person == person]

    def find(self, booking_id: int) -> Booking | None:
        return next((b for b in self.bookings if b.id == booking_id), None)

    def query(self, station: str | None = None, start: float | None = None, end: float | None = None,
              person: str | None = None) -> list[Booking]:
        return [b for b in self.bookings if b.id is not None
                and (station is None or b.station == station) and (person is None or b.person == person)
                and (start is None or b.end > start) and (end is None or b.start < end)]

    def boundaries_after(self, at: float) -> float | None:
        times = [t for b in self.bookings for t in (b.start, b.end) if t > at]
        return min(times) if times else None

    # --- changes --------------------------------------------------------------------------------

    def check(self, station: str, person: str, start: float, end: float, exempt: bool) -> None:
        """Raise BookingError when the slot may not be booked (exempt: an admin, no quotas)."""
        now, lim = self.now(), self.limits
        if not end > start:
            raise BookingError(400, f'"end" ({end:g}) must come after "start" ({start:g})')
        if end <= now:
            raise BookingError(400, f'that slot ended at {clock(end)}; book one that ends in the future')
        if end - start > lim.slot + SLACK:
            raise BookingError(400, f'a slot lasts at most {lim.slot / 60:g} minutes (--slot-minutes), not '
                                    f'{(end - start) / 60:g}')
        for b in self.bookings:
            if b.start < end and start < b.end:
                if b.station == station:
                    raise BookingError(409, f'{station} is booked by {b.name} from {clock(b.start)} to '
                                            f'{clock(b.end)} (booking {b.id}); pick another time or station')
                if b.person == person:
                    raise BookingError(409, f'you have {b.station} booked from {clock(b.start)} to '
                                            f'{clock(b.end)} (booking {b.id}): one station at a time')
        if exempt:
            return
        if lim.ahead and start - now > lim.ahead:
            raise BookingError(429, f'slots may be booked at most {lim.ahead / 86400:g} days ahead '
                                    '(--booking-ahead)')
        day = datetime.date.fromtimestamp(start)
        week = day.isocalendar()[:2]
        mine = self.of(person)
        same_day = sum(1 for b in mine if datetime.date.fromtimestamp(b.start) == day)
        if lim.per_day and same_day >= lim.per_day:
            raise BookingError(429, f'{lim.per_day} slots a day per person (--booking-per-day): you have '
                                    f'{same_day} on {day.isoformat()}')
        same_week = sum(1 for b in mine if datetime.date.fromtimestamp(b.start).isocalendar()[:2] == week)
        if lim.per_week and same_week >= lim.per_week:
            raise BookingError(429, f'{lim.per_week} slots a week per person (--booking-per-week): you have '
                                    f'{same_week} that week')

    async def add(self, station: str, person: str, name: str, start: float, end: float, *,
                  exempt: bool = False) -> Booking:
        """Check and keep a booking. It holds its place in memory at once (a second request for
        the same time, in while this one is written, sees it) and gets its id from the store."""
        if await courses.has_left(self.store, person):   # before check: nothing awaits between check and insort
            raise BookingError(403, 'you are no longer a member of this course in the LMS, so you cannot book a '
                                    'station; ask your teacher')
        self.check(station, person, start, end, exempt)
        booking = Booking(station, person, name, float(start), float(end))
        bisect.insort(self.bookings, booking, key=lambda b: b.start)
        row = {'station': station, 'person': person, 'name': name, 'start_at': booking.start,
               'end_at': booking.end, 'created_at': booking.created}
        def insert(c: sa.Connection) -> int:
            if self.fleet is not None:   # another gateway may book the same time now: PostgreSQL decides
                c.execute(sa.select(sa.func.pg_advisory_xact_lock(self.fleet.booking_key)))
                clash = c.execute(sa.select(TABLE.c.name).where(
                    TABLE.c.start_at < booking.end, TABLE.c.end_at > booking.start,
                    (TABLE.c.station == station) | (TABLE.c.person == person))).first()
                if clash is not None:
                    raise BookingError(409, f'{clash.name} booked {station} or you that time through another '
                                            'gateway a moment ago; pick another time or station')
            return c.execute(sa.insert(TABLE).values(**row)).inserted_primary_key[0]
        try:
            booking.id = await self.store.run(insert)
        except Exception:
            self.bookings.remove(booking)
            raise
        self._changed()
        if self.fleet is not None:
            self.fleet.notify('bookings')
        return booking

    async def remove(self, booking: Booking) -> None:
        await self.store.run(lambda c: c.execute(sa.delete(TABLE).where(TABLE.c.id == booking.id)))
        if booking in self.bookings:
            self.bookings.remove(booking)
        self._changed()
        if self.fleet is not None:
            self.fleet.notify('bookings')

    def _changed(self) -> None:
        if self.events is not None:
            self.events.timetable_changed()

    def forget_old(self) -> None:
        """Bookings older than the quotas look are dropped from memory (the store keeps them)."""
        since = self.now() - 8 * 86400.0
        self.bookings = [b for b in self.bookings if b.end > since]


class Slots(Hook):
    """The timer that starts and ends slots (see the module docstring)."""

    def __init__(self, timetable: Timetable, *, events: SlotEvents, caller: Caller, stations, lease,
                 stops: Stops, reset: str | None = None, queue=None):
        """events: told of each slot's end; caller: the backend, for the reset; queue: the walk-ins'
        line (rules.queue), for the API."""
        self.timetable, self.stations, self.lease = timetable, stations, lease
        self.events, self.caller, self.queue = events, caller, queue
        self.stops, self.reset = stops, reset
        self.active: dict[str, Booking] = {}          # station -> the booking whose slot is on
        self.resets: set[asyncio.Task] = set()
        self.timer: asyncio.TimerHandle | None = None
        self.tick()

    def on_timetable_changed(self) -> None:
        self.tick()

    def tick(self) -> None:
        """Bring every station to the booking its slot is on now; sleep until the next boundary."""
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None
        now = self.timetable.now()
        stations = set(self.stations.stations()) | set(self.active)
        for station in sorted(stations):
            want = self.timetable.current(station, now + LATE)
            have = self.active.get(station)
            if have is want:
                continue
            if have is not None:
                self._end(station, have, now)
            if want is not None:
                self._start(station, want)
        for station, (_, until) in list(self.timetable.ended.items()):
            if until <= now:
                del self.timetable.ended[station]
        self.timetable.forget_old()
        self.stations.refresh()
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        nxt = self.timetable.boundaries_after(now + LATE)
        # woken just past the boundary: a loop's timer may fire a millisecond early (uvloop), and
        # what is announced then (the slot on now) reads the clock without LATE
        delay = MAX_SLEEP if nxt is None else min(MAX_SLEEP, max(0.0, nxt - self.timetable.now()) + LATE)
        self.timer = loop.call_later(delay, self.tick)

    def _start(self, station: str, booking: Booking) -> None:
        self.active[station] = booking
        self.timetable.ended.pop(station, None)
        log.info('slot of %s on %s begins (booking %s, until %s)', booking.name, station, booking.id,
                 clock(booking.end))
        given_back = self.stations.seat(station, booking.person, booking.name, booking.end)
        if self.lease is not None:
            self.lease.hand_over(station, booking.person, f'{booking.name}\'s booked slot began')
            for ns in given_back:   # one station at a time: the walk-in she had is over
                self.lease.hand_over(ns, None, f'{booking.name}\'s booked slot on {station} began')

    def _end(self, station: str, booking: Booking, now: float) -> None:
        """The slot is over: the same stop as the teacher's, the booker's runs end, the reset."""
        del self.active[station]
        log.info('slot of %s on %s ends (booking %s)', booking.name, station, booking.id)
        why = f'{booking.name}\'s slot on {station} ended'
        if self.lease is not None:
            self.lease.hand_over(station, None, why)
        self.stops.stop_group(station, self.lease.group if self.lease is not None else None)
        self.events.slot_ended(station, booking.person, why)
        self.stations.unseat(station, booking.person, why)
        nxt = self.timetable.next(station, now)
        self.timetable.ended[station] = (booking.person, nxt.start if nxt is not None else now + self.timetable.limits.slot)
        if self.reset:
            task = asyncio.ensure_future(self._reset_once(station, booking))
            self.resets.add(task)
            task.add_done_callback(self.resets.discard)

    async def _reset_once(self, station: str, booking: Booking) -> None:
        """The reset, by one gateway of a fleet: the one whose claim of it the database takes first
        (it waits for the database: a reset late is better than two)."""
        fleet = self.timetable.fleet
        if fleet is None or await fleet.once(f'reset {station} {booking.start:.3f} {booking.end:.3f}'):
            await self._reset(station)
        else:
            log.info('slot end: %s reset by another gateway of the fleet', station)

    async def _reset(self, station: str) -> None:
        """The --station-reset service in the station's namespace (std_srvs Empty or Trigger)."""
        name = f'{station}/{self.reset.strip("/")}'
        backend = self.caller
        type = next((t for n, t in backend.services() if n == name), None)
        if type is None:
            log.warning('slot end: no service %s to reset %s', name, station)
            return
        if type not in RESET_TYPES:
            log.warning('slot end: %s is %s, not std_srvs Empty or Trigger; not called', name, type)
            return
        try:
            reply = await backend.call_service(name, type, {}, RESET_TIMEOUT)
        except Exception as e:   # a robot that fails its reset: said in the log, the slot still ends
            log.warning('slot end: %s failed: %s', name, e)
            return
        if type.endswith('Trigger') and not reply.get('success', True):
            log.warning('slot end: %s said: %s', name, reply.get('message'))
        else:
            log.info('slot end: %s reset (%s)', station, name)

    def on_shutdown(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None
        for task in self.resets:
            task.cancel()
