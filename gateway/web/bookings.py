"""The bookings API (``--booking``): slots per station, booked ahead (rules.bookings keeps them
and ends each slot on time).

POST   /api/bookings      {"station", "start", "end"} (epoch s; an admin may add "for": a person's
                          name or id, with --auth, to book for them: a token's name, or someone
                          who signed in, LMS launches included; 409 when a name is several
                          people's, naming their ids) -> 201 the booking; 400 a bad slot
                          (too long, ended, end before start), 403 a viewer, 404 no such station,
                          409 it overlaps a booking of the station (or one of yours elsewhere),
                          429 past a quota (per day, per week, how far ahead; admins have none)
GET    /api/bookings[?station=&from=&to=]  -> {"enabled": true, "bookings": [...], "now", "slot",
                          "stations", "me", "role", "limits"}: each booking {"id", "station", "name"
                          (its booker's; "owner" too, as runs and recordings say), "start", "end",
                          "mine"}; without --booking {"enabled": false} (other routes answer 404)
DELETE /api/bookings/ID   -> 200 (its booker or an admin; 403 others); a slot on now ends at once
GET    /api/queue         -> {"place", "queued", "wait" (s, estimated; null: unknown), "seated", "station",
                          "line"}: the walk-ins' line when every station is taken (rules.queue)
POST   /api/queue         -> 201 join it (409 with a station already); DELETE /api/queue: leave it
GET    /api/people        -> {"people": [{"id", "name", "role", "kind", "seen"}]}: who an admin may book
                          for (everyone who signed in here, newest first, then the LMS courses' active
                          members who never launched yet: kind "lti", seen null); admins only
GET    /api/bookings.ics  -> the caller's bookings as an iCalendar feed (an admin's: everyone's);
                          a calendar app subscribes with ?token= in the address

A person is who owns a station (rules.stations.person_of): the signed-in name with --auth, else
the browser's id. The gateway's clock decides (``now`` in every answer lets a page show the time
left by the gateway's clock whatever its own says).
"""

from __future__ import annotations

import datetime
import re

import icalendar
import tornado.web

from ..lab.people import people
from ..rules.access import Action, Area, allowed
from ..rules.bookings import Slots
from ..auth.sessions import Sessions
from ..rules.stations import person_of
from ..store import Store
from .api import JsonHandler, authorize, body_json, query_number

MAX_BODY = 4096
ID = re.compile(r'[0-9]{1,12}')


class _Handler(JsonHandler):
    def initialize(self, slots: Slots | None, sessions: Sessions | None, store: Store) -> None:
        self.slots, self.sessions, self.store = slots, sessions, store

    def prepare(self) -> None:
        if self.slots is None and not (self.request.method == 'GET' and isinstance(self, BookingListHandler)):
            raise tornado.web.HTTPError(404, 'bookings are off on this gateway (start it with --booking)')

    def who(self, area: Area = Area.BOOKINGS, action: Action | None = None):
        """(identity or None, person or None), when they may ``action`` in ``area`` (``web.api.authorize``)."""
        identity = authorize(self, area, action)
        return identity, person_of(identity, self.request.cookies)

    def number(self, name: str, value) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 1e11:
            raise tornado.web.HTTPError(400, f'"{name}" is a time in epoch seconds, not {str(value)[:40]!r}')
        return float(value)

    def arg_time(self, name: str) -> float | None:
        return query_number(self, name, None, 'a time in epoch seconds', low=0, high=1e11)


def _view(booking, key: str | None) -> dict:
    return {**booking.json(), 'mine': key is not None and booking.person == key}


class BookingListHandler(_Handler):
    def get(self) -> None:
        if self.slots is None:   # the pages ask on every gateway: an answer, not an error in their console
            self.finish({'enabled': False, 'bookings': []})
            return
        identity, key = self.who()
        timetable = self.slots.timetable
        station = self.get_query_argument('station', None) or None
        found = timetable.query(station, self.arg_time('from'), self.arg_time('to'))
        lim = timetable.limits
        self.finish({'enabled': True, 'bookings': [_view(b, key) for b in found], 'now': timetable.now(),
                     'slot': lim.slot, 'stations': list(self.slots.stations.stations()),
                     'me': identity.name if identity is not None else key,
                     'role': identity.role if identity is not None else None,
                     'limits': {'per_day': lim.per_day, 'per_week': lim.per_week, 'ahead': lim.ahead}})

    async def post(self) -> None:
        identity, key = self.who()
        if key is None:
            raise tornado.web.HTTPError(403, 'a booking needs a person: sign in, or book from the gateway\'s pages')
        body = body_json(self, MAX_BODY)
        station = body.get('station')
        if not isinstance(station, str) or station not in self.slots.stations.stations():
            known = ', '.join(self.slots.stations.stations()) or 'none'
            raise tornado.web.HTTPError(404 if isinstance(station, str) else 400,
                                        f'"station" is one of the stations ({known}), not {str(station)[:40]!r}')
        start, end = self.number('start', body.get('start')), self.number('end', body.get('end'))
        exempt = allowed(identity, Action.EXEMPT, Area.BOOKINGS)   # past the day's and week's limits
        name = identity.name if identity is not None else f'guest {key.split()[-1][:6]}'
        booker = key
        behalf = body.get('for')
        if behalf is not None:   # the teacher books a slot for a student
            if not allowed(identity, Action.MANAGE, Area.BOOKINGS):
                raise tornado.web.HTTPError(403, '"for" (booking for someone else) is for admins')
            if not isinstance(behalf, str) or not 0 < len(behalf.strip()) <= 100:
                raise tornado.web.HTTPError(400, '"for" is the name or id of a person')
            booker, name = await self.behalf(behalf.strip())
        booking = await self.slots.timetable.add(station, booker, name, start, end, exempt=exempt)   # BookingError: answered by Handler
        self.set_status(201)
        self.finish(_view(booking, key))


    async def behalf(self, who: str) -> tuple[str, str]:
        """(person key, name) of whom "for" names: someone who signed in here (by id or name), else
        an active member of an LMS course (the roster: before their first launch), else a name of
        the tokens file (whose key is the name itself)."""
        found = await people(self.sessions, self.store, who)
        if len(found) > 1:
            ids = ', '.join(f'{p["id"]} ({p["kind"]}, {p["role"]})' for p in found[:5])
            raise tornado.web.HTTPError(409, f'several people are named {who!r}: book by id, one of {ids}')
        if found:
            return f'user {found[0]["id"]}', found[0]['name']
        return f'user {who}', who


class PeopleHandler(_Handler):
    def prepare(self) -> None:
        pass   # the people are known with or without --booking

    async def get(self) -> None:
        self.who(Area.PEOPLE)
        self.finish({'people': await people(self.sessions, self.store)})


class BookingHandler(_Handler):
    def _booking(self, booking_id: str):
        booking = self.slots.timetable.find(int(booking_id)) if ID.fullmatch(booking_id) else None
        if booking is None:
            raise tornado.web.HTTPError(404, f'no booking {booking_id[:20]!r}')
        return booking

    def get(self, booking_id: str) -> None:
        _, key = self.who()
        self.finish(_view(self._booking(booking_id), key))

    async def delete(self, booking_id: str) -> None:
        identity, key = self.who(action=Action.SEE)   # a booking of one's own: cancelled by whoever may see it
        booking = self._booking(booking_id)
        if not allowed(identity, Action.CHANGE, Area.BOOKINGS, booking.person):
            raise tornado.web.HTTPError(403, f'booking {booking.id} is {booking.name}\'s; only they or an admin '
                                             'may cancel it')
        if booking.end <= self.slots.timetable.now() and not allowed(identity, Action.MANAGE, Area.BOOKINGS):
            raise tornado.web.HTTPError(409, f'booking {booking.id} has ended; past slots stay on the timetable')
        await self.slots.timetable.remove(booking)
        self.finish({**_view(booking, key), 'deleted': True})


class CalendarHandler(_Handler):
    def set_default_headers(self) -> None:
        self.set_header('Cache-Control', 'no-store')

    def get(self) -> None:
        identity, key = self.who()
        admin = allowed(identity, Action.MANAGE, Area.BOOKINGS)   # everyone's calendar
        found = self.slots.timetable.query(person=None if admin else key) if (key or admin) else []
        cal = icalendar.Calendar()
        cal.add('prodid', '-//rosgate//bookings//EN')
        cal.add('version', '2.0')
        cal.add('x-wr-calname', f'rosgate bookings{"" if admin else f" of {identity.name if identity else key}"}')
        host = self.request.host_name
        for b in found:
            event = icalendar.Event()
            event.add('uid', f'booking-{b.id}@{host}')
            event.add('summary', f'Robot {b.station}' + (f' ({b.name})' if admin else ''))
            event.add('dtstart', datetime.datetime.fromtimestamp(b.start, datetime.timezone.utc))
            event.add('dtend', datetime.datetime.fromtimestamp(b.end, datetime.timezone.utc))
            event.add('dtstamp', datetime.datetime.fromtimestamp(b.created, datetime.timezone.utc))
            event.add('location', b.station)
            cal.add_component(event)
        self.set_header('Content-Type', 'text/calendar; charset=utf-8')
        self.finish(cal.to_ical())


class QueueHandler(_Handler):
    """/api/queue: the walk-ins' line (rules.queue) when every station is taken."""

    def answer(self, key: str | None) -> None:
        slots = self.slots
        body = slots.queue.status(key, slots.stations) if key is not None else {
            'place': None, 'queued': len(slots.queue.line), 'seated': None, 'wait': None,
            'line': [w.name for w in slots.queue.line]}
        mine = next((ns for ns in slots.stations.stations()
                     if (o := slots.stations.owner(ns)) is not None and o.person == key), None)
        self.finish({**body, 'station': mine})

    def get(self) -> None:
        _, key = self.who(Area.QUEUE)
        self.answer(key)

    def post(self) -> None:
        identity, key = self.who(Area.QUEUE)
        if key is None:
            raise tornado.web.HTTPError(403, 'the queue needs a person: sign in, or join from the gateway\'s pages')
        stations = self.slots.stations
        mine = next((ns for ns in stations.stations() if (o := stations.owner(ns)) is not None and o.person == key), None)
        if mine is not None:
            raise tornado.web.HTTPError(409, f'{mine} is your station already; no need to queue')
        name = identity.name if identity is not None else f'guest {key.split()[-1][:6]}'
        self.slots.queue.join(key, name)
        self.set_status(201)
        self.answer(key)

    def delete(self) -> None:
        _, key = self.who(Area.QUEUE, Action.SEE)   # leaving: whoever may see the queue
        if key is None or not self.slots.queue.leave(key):
            raise tornado.web.HTTPError(404, 'you are not in the queue')
        self.answer(key)


def booking_routes(slots: Slots | None, sessions: Sessions | None, store: Store) -> list:
    """``slots``: the booked slots (``Rules.slots``, None without --booking); ``sessions``: who signed in
    (``Policy.sessions``, None with auth off)."""
    kw = {'slots': slots, 'sessions': sessions, 'store': store}
    return [(r'/api/bookings\.ics', CalendarHandler, kw), (r'/api/bookings/?', BookingListHandler, kw),
            (r'/api/bookings/([^/]+)', BookingHandler, kw), (r'/api/queue/?', QueueHandler, kw),
            (r'/api/people/?', PeopleHandler, kw)]
