"""The rules' side of a fleet of gateways (``store.fleet``): what another gateway did, done here.

Each rule is given the fleet at construction (they tell it what they hold and do); ``FleetPart`` is
the fleet's one listener (``store.fleet.FleetListener``, given to ``Fleet.start``) and hands what the
others did to the rule it concerns, on the loop. Each shared rule is a row, mirrored and read back every
second (``store.fleet``); a change arrives as the row's change, whether it was heard at once
(NOTIFY) or read after a gap:

- ``stop`` (a group): the teacher's Stop in force -> ``lease.stopped_elsewhere``; its end ->
  ``lease.unhalted_elsewhere``; a lease taken checks it in the same transaction (settle.py);
- ``bar`` (a station): the teacher's Release of a person -> ``stations.barred_elsewhere``;
- ``queue`` (a person): the walk-in line -> ``queue.mirror``;
- ``revoked`` (a session): a logout anywhere -> ``sessions.revoked_elsewhere`` (which acks it);
- holds: a claim or lease of ours gone (taken, ended by a Stop or Release, lapsed) -> ``lost``;
  another gateway's lease lapsed (it died) -> ``lease.lapsed_elsewhere`` (its robot zeroed);
- the timetable: re-read when its rows change (``bookings`` reader), a slot's reset done once.

A sign-in is heard as an event (and its row read); nothing else travels as a one-off notice.
Nothing here waits on the database.
"""

from __future__ import annotations

import asyncio
import logging

import sqlalchemy as sa

from .bookings import TABLE as BOOKINGS
from .hooks import Hook

log = logging.getLogger('rosgate.fleet')


class FleetPart(Hook):
    """What the other gateways did, handed to the rule it concerns (``store.fleet.FleetListener``);
    starts the fleet with the gateway's loop and leaves it (its holds deleted) at shutdown."""

    def __init__(self, fleet, *, lease, stations, sessions, timetable):
        self.fleet, self.lease, self.stations, self.sessions, self.timetable = fleet, lease, stations, sessions, timetable
        self.tasks: set[asyncio.Task] = set()
        self.bookings: tuple | None = None    # the bookings' version last read

    def start(self) -> None:
        readers = {}
        if self.sessions is not None:
            readers['sessions'] = self.sessions.created_since
        if self.timetable is not None:
            readers['bookings'] = bookings_version
        try:
            self.fleet.start(asyncio.get_running_loop(), self, readers)
        except RuntimeError:        # no loop (a test composing rules alone): the fleet stays quiet
            log.warning('fleet: no event loop; the other gateways are not heard')

    def later(self, coro) -> None:
        task = asyncio.ensure_future(coro)
        self.tasks.add(task)
        task.add_done_callback(self.tasks.discard)

    # --- store.fleet.FleetListener ------------------------------------------------------------

    def on_event(self, what: str, event: dict) -> None:
        if what in ('hold', 'drop', 'end'):
            self.stations.refresh()
            if self.lease is not None:
                self.lease.refresh()
        elif what == 'login' and self.sessions is not None:
            self.sessions.heard_login(event)
        elif what == 'bookings' and self.timetable is not None:
            self.later(self.timetable.reload())

    def on_state_changed(self, kind: str, name: str, old: dict | None, new: dict | None) -> None:
        if kind == 'bar':
            self.stations.barred_elsewhere(name, old, new)
        elif kind == 'queue' and self.stations.queue is not None:
            self.stations.queue.mirror(name, old, new)
        elif kind == 'stop' and self.lease is not None:
            if new is not None:
                self.lease.stopped_elsewhere(name, new.get('by', 'the teacher'))
            else:
                self.lease.unhalted_elsewhere(name)
        elif kind == 'revoked' and self.sessions is not None and new is not None:
            self.sessions.revoked_elsewhere(name)

    def on_hold_lost(self, kind: str, name: str, holder, why: str | None) -> None:
        if kind == 'claim':
            self.stations.lost_elsewhere(name, holder, why)
        elif kind == 'lease' and self.lease is not None:
            self.lease.lost_elsewhere(name, holder, why)

    def on_hold_lapsed(self, kind: str, name: str, holder) -> None:
        if kind == 'lease' and self.lease is not None:
            self.lease.lapsed_elsewhere(name, holder)

    def on_cut_off(self) -> None:
        if self.lease is not None:
            self.lease.cut_off()

    def on_back(self) -> None:
        if self.lease is not None:
            self.lease.refresh()

    def on_read(self, name: str, data) -> None:
        if name == 'sessions':          # the sessions begun since: a sign-in not heard
            self.sessions.heard_created(data)
        elif name == 'bookings':        # the bookings' version: the timetable read again when it changed
            if self.bookings is not None and self.bookings != data:
                self.later(self.timetable.reload())
            self.bookings = data

    # --- rules.hooks.Hook -----------------------------------------------------------------------

    def on_shutdown(self) -> None:
        for task in self.tasks:
            task.cancel()
        self.fleet.close()


def bookings_version(c: sa.Connection, since: float) -> tuple:
    """What changes whenever a booking is made or removed (the timetable is read again then)."""
    return tuple(c.execute(sa.select(sa.func.count(), sa.func.coalesce(sa.func.max(BOOKINGS.c.id), 0),
                                     sa.func.coalesce(sa.func.sum(BOOKINGS.c.id), 0))).one())
