"""The rules' side of a fleet of gateways (``store.fleet``): what another gateway did, done here.

``join`` hands each rule the fleet (they tell it what they hold and do) and wires what the others
did to the rule it concerns, on the loop. Each shared rule is a row, mirrored and read back every
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
    """Starts the fleet with the gateway's loop and leaves it (its holds deleted) at shutdown."""

    def __init__(self, fleet):
        self.fleet = fleet
        self.tasks: set[asyncio.Task] = set()

    def later(self, coro) -> None:
        task = asyncio.ensure_future(coro)
        self.tasks.add(task)
        task.add_done_callback(self.tasks.discard)

    def on_shutdown(self) -> None:
        for task in self.tasks:
            task.cancel()
        self.fleet.close()


def bookings_version(c: sa.Connection, since: float) -> tuple:
    """What changes whenever a booking is made or removed (the timetable is read again then)."""
    return tuple(c.execute(sa.select(sa.func.count(), sa.func.coalesce(sa.func.max(BOOKINGS.c.id), 0),
                                     sa.func.coalesce(sa.func.sum(BOOKINGS.c.id), 0))).one())


def join(fleet, *, lease, stations, sessions, timetable) -> FleetPart:
    part = FleetPart(fleet)
    stations.fleet = fleet
    fleet.lost['claim'] = stations.lost_elsewhere
    fleet.changed['bar'] = stations.barred_elsewhere
    for what in ('hold', 'drop', 'end'):
        fleet.on(what, lambda e: stations.refresh())
    if stations.queue is not None:
        stations.queue.fleet = fleet
        fleet.changed['queue'] = stations.queue.mirror
    if lease is not None:
        lease.fleet = fleet
        for what in ('hold', 'drop', 'end'):
            fleet.on(what, lambda e: lease.refresh())
        fleet.lost['lease'] = lease.lost_elsewhere
        fleet.lapsed['lease'] = lease.lapsed_elsewhere
        fleet.changed['stop'] = lambda group, old, new: (
            lease.stopped_elsewhere(group, new.get('by', 'the teacher')) if new is not None
            else lease.unhalted_elsewhere(group))
        fleet.cut.append(lease.cut_off)
        fleet.back.append(lease.refresh)
    if sessions is not None:
        sessions.fleet = fleet
        fleet.on('login', sessions.heard_login)
        fleet.changed['revoked'] = lambda key, old, new: new is not None and sessions.revoked_elsewhere(key)
        fleet.reader('sessions', sessions.created_since, sessions.heard_created)
    if timetable is not None:
        timetable.fleet = fleet
        fleet.on('bookings', lambda e: part.later(timetable.reload()))
        known = []

        def changed(version: tuple) -> None:
            if known and known[0] != version:
                part.later(timetable.reload())
            known[:] = [version]
        fleet.reader('bookings', bookings_version, changed)
    try:
        fleet.start(asyncio.get_running_loop())
    except RuntimeError:        # no loop (a test composing rules alone): the fleet stays quiet
        log.warning('fleet: no event loop; the other gateways are not heard')
    return part
