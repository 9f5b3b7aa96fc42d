"""The rules' side of a fleet of gateways (``store.fleet``): what another gateway did, done here.

``join`` hands each rule the fleet (they tell it what they hold and do) and hears the others'
events on the loop: a hold lost to another gateway, the teacher's Stop, Release and the end of a
stop, a station given back, a sign-in and a sign-out, the timetable changed, the walk-in line. Nothing here waits on
the database: the events come from the fleet's LISTEN thread, the rules check its in-memory mirror.
"""

from __future__ import annotations

import asyncio
import logging

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


def join(fleet, *, lease, stations, sessions, timetable) -> FleetPart:
    part = FleetPart(fleet)
    stations.fleet = fleet
    fleet.lost['claim'] = stations.lost_elsewhere
    fleet.on('free', lambda e: stations.freed_elsewhere(e['station'], e['by'], e['person'], e.get('barred')))
    fleet.on('hold', lambda e: stations.refresh())
    fleet.on('drop', lambda e: stations.refresh())
    if stations.queue is not None:
        stations.queue.fleet = fleet
        fleet.on('queue', stations.queue.heard)
    if lease is not None:
        lease.fleet = fleet
        fleet.on('hold', lambda e: lease.refresh())
        fleet.on('drop', lambda e: lease.refresh())
        fleet.lost['lease'] = lease.lost_elsewhere
        fleet.lapsed['lease'] = lease.lapsed_elsewhere
        fleet.on('stop', lambda e: lease.stopped_elsewhere(e['group'], e['by']))
        fleet.on('release', lambda e: lease.released_elsewhere(e['group'], e['by']))
        fleet.on('unhalt', lambda e: lease.unhalted_elsewhere(e['group']))
    if sessions is not None:
        sessions.fleet = fleet
        fleet.on('login', sessions.heard_login)
        fleet.on('logout', lambda e: sessions.heard_logout(e['key']))
    if timetable is not None:
        timetable.fleet = fleet
        fleet.on('bookings', lambda e: part.later(timetable.reload()))
    try:
        fleet.start(asyncio.get_running_loop())
    except RuntimeError:        # no loop (a test composing rules alone): the fleet stays quiet
        log.warning('fleet: no event loop; the other gateways are not heard')
    return part
