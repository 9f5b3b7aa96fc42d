"""A fleet of gateways on one PostgreSQL (``--db postgresql+psycopg://…`` on each): what they share.

One gateway is one tornado process on one core; a lab of several classes runs several behind one
proxy, on one ROS graph. What must hold across them goes through PostgreSQL's own mechanisms, no
consensus of ours:

- *holds* (table ``fleet_holds``): one row per (kind, name) — a station's claim (``claim``), a
  group's driver lease (``lease``) — naming the person, who (for refusals) and the gateway. A
  row carries an expiry HOLD seconds ahead, refreshed every BEAT by its gateway: a gateway that
  dies (kill -9, a lost machine) loses its holds within HOLD seconds. Taking a hold is one
  ``INSERT … ON CONFLICT DO UPDATE … WHERE`` (the row is free, expired, ours or the same
  person's, or ``force``: an admin's takeover): PostgreSQL settles two gateways taking one hold
  at once, and the loser is told (``lost``).
- events (``NOTIFY rosgate_fleet``): a hold taken or dropped, the teacher's Stop and Release, a
  sign-in and a sign-out, a booking made or removed. Each gateway LISTENs on a connection of its
  own, on a thread that hands each event to the tornado loop: the others hear in a few ms.
- the *timekeeper* (``pg_try_advisory_lock`` on a connection of its own): one gateway does what
  must happen once per fleet (calling a station's reset at a slot's end, writing the history); if
  it dies its connection closes, PostgreSQL releases the lock, and another takes it within BEAT.

The rules never wait on the database on the publish path: what other gateways hold is mirrored in
memory (``held``), kept current by the events and by the beat's read of every live hold, so the
publish door checks a dict. A station's claim alone waits for PostgreSQL's word (``take``): two
students asking two gateways for one station at once get one yes and one no naming the holder. Writes go through this module's own thread, in the order they were asked.

Only a PostgreSQL store makes a fleet (``Fleet.of``); SQLite is one gateway, as before.
May import: ``settings`` and ``store``.
"""

from __future__ import annotations

import asyncio
import json
import logging
import queue
import secrets
import threading
import time
from dataclasses import dataclass
from typing import Callable

import sqlalchemy as sa

from . import METADATA

log = logging.getLogger('rosgate.fleet')
CHANNEL = 'rosgate_fleet'
TIMEKEEPER_KEY = 0x726F7367       # the advisory lock's key ("rosg")
BOOKING_KEY = 0x726F7368          # the transaction lock around a booking's insert
HOLD = 3.0                        # s a hold outlives its gateway's last beat
BEAT = 1.0                        # s between refreshes (HOLD / BEAT beats missed before a hold lapses)

HOLDS = sa.Table(
    'fleet_holds', METADATA,
    sa.Column('kind', sa.String(16), primary_key=True),
    sa.Column('name', sa.String(200), primary_key=True),
    sa.Column('person', sa.String(200), nullable=False),
    sa.Column('who', sa.String(300), nullable=False),
    sa.Column('gateway', sa.String(32), nullable=False),
    sa.Column('expires', sa.Float, nullable=False),
)
NOW = sa.literal_column('extract(epoch from clock_timestamp())', sa.Float)   # the database's clock, one for all


@dataclass
class Hold:
    person: str
    who: str
    gateway: str
    until: float     # time.monotonic() past which it no longer holds


class Fleet:
    """This gateway's part in the fleet: its holds, the others' (mirrored), events, the lock."""

    @classmethod
    def of(cls, store) -> 'Fleet | None':
        return cls(store) if store.engine.dialect.name == 'postgresql' else None

    def __init__(self, store):
        self.store, self.id = store, secrets.token_hex(6)
        self.mine: dict[tuple[str, str], tuple[str, str]] = {}   # (kind, name) -> (person, who)
        self.others: dict[tuple[str, str], Hold] = {}
        self.heard: dict[tuple[str, str], float] = {}   # when an event last changed a hold (monotonic)
        self.handlers: dict[str, list[Callable[[dict], None]]] = {}
        self.lost: dict[str, Callable[[str, Hold], None]] = {}   # kind -> fn(name, holder) on a hold lost
        self.lapsed: dict[str, Callable[[str, Hold], None]] = {}  # kind -> fn(name, holder): its gateway died
        self.timekeeper = False
        self.booking_key = BOOKING_KEY
        self.notified = 0              # events sent (figures: none per command)
        self._jobs: queue.SimpleQueue = queue.SimpleQueue()
        self._closing = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._dsn = store.engine.url.set(drivername='postgresql').render_as_string(hide_password=False)
        self._threads: list[threading.Thread] = []

    # --- on the loop --------------------------------------------------------------------------

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop
        self._read_holds(self.store.run_now(self._live_holds), time.monotonic())
        for target, name in ((self._listen, 'rosgate-fleet-listen'), (self._work, 'rosgate-fleet')):
            t = threading.Thread(target=target, name=name, daemon=True)
            t.start()
            self._threads.append(t)
        log.info('fleet: gateway %s on %s', self.id, self.store.url)

    def on(self, what: str, fn: Callable[[dict], None]) -> None:
        """fn(event) for each event ``what`` from another gateway, on the loop."""
        self.handlers.setdefault(what, []).append(fn)

    def held(self, kind: str, name: str) -> Hold | None:
        """Who holds (kind, name) through another gateway now, or None: a dict lookup."""
        h = self.others.get((kind, name))
        return h if h is not None and h.until > time.monotonic() else None

    def hold(self, kind: str, name: str, person: str, who: str, force: bool = False) -> None:
        """Take (or keep) a hold for this gateway; the others hear it. ``force``: over anyone's."""
        if self.mine.get((kind, name)) == (person, who) and not force:
            return
        self.mine[(kind, name)] = (person, who)
        self.others.pop((kind, name), None)
        self._jobs.put(('hold', kind, name, person, who, force))

    async def take(self, kind: str, name: str, person: str, who: str) -> Hold | None:
        """Take a hold and wait for PostgreSQL's word: None when it is this gateway's, else who holds
        it. For a station's claim, which a person waits for and which two gateways may be asked for
        at once: one round trip, off the loop, never on the publish path (``hold`` answers from memory)."""
        theirs = await asyncio.to_thread(self.store.run_now, lambda c: self._insert(c, kind, name, person, who))
        key = (kind, name)
        if theirs is None:
            self.mine[key] = (person, who)
            self.others.pop(key, None)
            return None
        if self.mine.get(key) == (person, who):
            del self.mine[key]        # what ``hold`` queued for it loses quietly: the caller answers
        holder = Hold(theirs.person, theirs.who, theirs.gateway, time.monotonic() + HOLD)
        self.others[key] = holder
        return holder

    def drop(self, kind: str, name: str) -> None:
        if self.mine.pop((kind, name), None) is not None:
            self._jobs.put(('drop', kind, name))

    def notify(self, what: str, **event) -> None:
        """Tell the other gateways (``on(what, fn)`` there hears it)."""
        self._jobs.put(('notify', what, event))

    def _heard(self, payload: str) -> None:
        try:
            event = json.loads(payload)
        except ValueError:
            return
        if event.get('gw') == self.id:
            return
        what = event.get('ev')
        if what in ('hold', 'drop'):
            self.heard[(event['k'], event['name'])] = time.monotonic()
        if what == 'hold':
            key = (event['k'], event['name'])
            self.others[key] = Hold(event['person'], event['who'], event['gw'], time.monotonic() + HOLD)
            if key in self.mine and (self.mine[key][0] != event['person'] or event.get('force')):
                self.mine.pop(key)
                self._lose(key, self.others[key])
        elif what == 'drop':
            h = self.others.get((event['k'], event['name']))
            if h is not None and h.gateway == event['gw']:
                del self.others[(event['k'], event['name'])]
        for fn in self.handlers.get(what, ()):
            try:
                fn(event)
            except Exception:
                log.exception('fleet: %s event failed', what)

    def _lose(self, key: tuple[str, str], holder: Hold) -> None:
        fn = self.lost.get(key[0])
        if fn is not None:
            fn(key[1], holder)

    def _lost_hold(self, kind: str, name: str, person: str, who: str, row) -> None:
        """Our INSERT found the hold someone else's (both took it at once): we give way."""
        holder = Hold(row.person, row.who, row.gateway, time.monotonic() + HOLD)
        self.others[(kind, name)] = holder
        if self.mine.get((kind, name)) == (person, who):
            del self.mine[(kind, name)]
            self._lose((kind, name), holder)

    def _read_holds(self, rows, read_at: float) -> None:
        """The beat's read of every live hold; what an event changed since the read began stays."""
        now = time.monotonic()
        seen = {}
        for r in rows:
            if r.gateway != self.id:
                seen[(r.kind, r.name)] = Hold(r.person, r.who, r.gateway, now + r.left)
        for key, at in list(self.heard.items()):
            if at >= read_at:
                seen.pop(key, None)
                if key in self.others:
                    seen[key] = self.others[key]
            elif at < now - 60:
                del self.heard[key]
        gone = [(key, h) for key, h in self.others.items() if key not in seen]
        self.others = seen
        for (kind, name), h in gone:   # not given back (that is an event): it lapsed, its gateway is gone
            fn = self.lapsed.get(kind)
            if fn is not None:
                try:
                    fn(name, h)
                except Exception:
                    log.exception('fleet: a lapsed %s of %s', kind, name)

    def close(self) -> None:
        self._closing.set()
        self._jobs.put(('close',))
        for t in self._threads:
            t.join(timeout=3)

    # --- on the fleet's threads ---------------------------------------------------------------

    def _post(self, fn, *args) -> None:
        if self._loop is not None and not self._loop.is_closed():
            self._loop.call_soon_threadsafe(fn, *args)

    def _listen(self) -> None:
        import psycopg
        while not self._closing.is_set():
            try:
                with psycopg.connect(self._dsn, autocommit=True) as conn:
                    conn.execute(f'LISTEN {CHANNEL}')
                    while not self._closing.is_set():
                        for n in conn.notifies(timeout=0.5):
                            self._post(self._heard, n.payload)
            except Exception as e:
                if not self._closing.is_set():
                    log.warning('fleet: listening failed (%s); again in %s s', e, BEAT)
                    self._closing.wait(BEAT)

    def _live_holds(self, c: sa.Connection):
        return c.execute(sa.select(HOLDS, (HOLDS.c.expires - NOW).label('left'))
                         .where(HOLDS.c.expires > NOW)).all()

    def _work(self) -> None:
        """Writes in order; every BEAT: our holds refreshed, the others' read, the lock tried."""
        import psycopg
        lock = None
        next_beat = 0.0
        while True:
            try:
                job = self._jobs.get(timeout=max(0.0, next_beat - time.monotonic()))
            except queue.Empty:
                job = None
            if job is not None and job[0] == 'close':
                break
            try:
                if job is not None:
                    self.store.run_now(lambda c: self._do(c, job))
                if time.monotonic() >= next_beat:
                    next_beat = time.monotonic() + BEAT
                    if lock is None or lock.closed:
                        lock = psycopg.connect(self._dsn, autocommit=True)
                        self.timekeeper = False
                    if not self.timekeeper:
                        self.timekeeper = bool(lock.execute('SELECT pg_try_advisory_lock(%s)',
                                                            (TIMEKEEPER_KEY,)).fetchone()[0])
                        if self.timekeeper:
                            log.info('fleet: this gateway keeps time (slot resets, history)')
                    read_at = time.monotonic()
                    rows = self.store.run_now(self._beat)
                    self._post(self._read_holds, rows, read_at)
            except Exception as e:
                log.warning('fleet: %s', e)
                self.timekeeper = False
                if lock is not None:
                    lock.close()
                self._closing.wait(BEAT)
        if lock is not None:
            lock.close()
        try:
            self.store.run_now(lambda c: c.execute(HOLDS.delete().where(HOLDS.c.gateway == self.id)))
        except Exception:
            pass

    def _send(self, c: sa.Connection, what: str, **event) -> None:
        event.update(ev=what, gw=self.id)
        c.execute(sa.select(sa.func.pg_notify(CHANNEL, json.dumps(event))))
        self.notified += 1

    def _do(self, c: sa.Connection, job) -> None:
        if job[0] == 'notify':
            self._send(c, job[1], **job[2])
        elif job[0] == 'drop':
            _, kind, name = job
            c.execute(HOLDS.delete().where(HOLDS.c.kind == kind, HOLDS.c.name == name, HOLDS.c.gateway == self.id))
            self._send(c, 'drop', k=kind, name=name)
        else:
            _, kind, name, person, who, force = job
            theirs = self._insert(c, kind, name, person, who, force)
            if theirs is not None:
                self._post(self._lost_hold, kind, name, person, who, theirs)

    def _insert(self, c: sa.Connection, kind: str, name: str, person: str, who: str, force: bool = False):
        """The hold taken (the others told): None; or the row of whoever holds it."""
        from sqlalchemy.dialects.postgresql import insert
        row = dict(kind=kind, name=name, person=person, who=who, gateway=self.id)
        stmt = insert(HOLDS).values(**row, expires=NOW + HOLD)
        cond = None if force else ((HOLDS.c.expires < NOW) | (HOLDS.c.gateway == self.id)
                                   | (HOLDS.c.person == person))
        stmt = stmt.on_conflict_do_update(index_elements=['kind', 'name'], where=cond, set_=dict(
            person=stmt.excluded.person, who=stmt.excluded.who, gateway=stmt.excluded.gateway,
            expires=stmt.excluded.expires)).returning(HOLDS.c.gateway)
        if c.execute(stmt).first() is None:
            return c.execute(sa.select(HOLDS).where(HOLDS.c.kind == kind, HOLDS.c.name == name)).first()
        self._send(c, 'hold', k=kind, name=name, person=person, who=who, force=force)
        return None

    def _beat(self, c: sa.Connection):
        c.execute(sa.update(HOLDS).where(HOLDS.c.gateway == self.id).values(expires=NOW + HOLD))
        c.execute(HOLDS.delete().where(HOLDS.c.expires < NOW - 60))   # long-dead gateways' rows
        return self._live_holds(c)
