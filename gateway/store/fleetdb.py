"""The fleet's side in PostgreSQL (``store.fleet``): its tables, its statements, and the threads that
talk to the database so the event loop never does.

Tables (declared here, once):

- ``fleet_holds`` (kind, name) -> person, who, gateway, expires: a station's claim (``claim``), a
  group's driver lease (``lease``); a row lives HOLD seconds past its gateway's last beat.
- ``fleet_state`` (kind, name) -> value (JSON), gateway, at, until: what must hold across gateways
  and outlive the gateway that did it: a Stop in force (``stop``, by group), a teacher's Release
  that bars a person from a station (``bar``), a place in the walk-in line (``queue``), a signed-out
  session (``revoked``, by the session id's hash, kept until the session would have ended), a
  thing done once per fleet (``once``, a station's reset at a slot's end). ``at``: the database's
  clock when written; ``until``: when the timekeeper may delete it (None: while it holds).
- ``fleet_gateways`` id -> expires, seen, started: the gateways alive (a row lives HOLD seconds past
  its last beat); ``seen``: the database's clock up to which that gateway has applied the shared
  state (a logout waits until every live gateway has seen it, or has lapsed).

``Worker`` runs every statement on one thread, in the order asked: writes are retried until the
database takes them (a Stop written while the database is away is written when it returns, and
nothing read before it is applied over it), and every BEAT it refreshes this gateway's rows and
reads the whole shared state back (``Read``). ``listen`` keeps a LISTEN connection and asks for a
read at once whenever it (re)connects: what was notified while it was away is read, not lost.
Every connection is named ``rosgate-PID-ROLE`` (``application_name``), so an operator (or a test)
finds a gateway's connections in ``pg_stat_activity``.

May import: ``settings`` and ``store``.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import sqlalchemy as sa

from . import METADATA, pg_connect_args as connect_args

log = logging.getLogger('rosgate.fleet')
CHANNEL = 'rosgate_fleet'
TIMEKEEPER_KEY = 0x726F7367       # the advisory lock's key ("rosg")
BOOKING_KEY = 0x726F7368          # the transaction lock around a booking's insert
LEASE_KEY = 0x726F7369            # with the group's hash: a lease taken and a Stop written one at a time
HOLD = 3.0                        # s a row outlives its gateway's last beat
BEAT = 1.0                        # s between refreshes and reads of the shared state
RETRY = (0.1, 0.25, 0.5, 1.0)     # s between tries while the database does not answer
SINCE_MARGIN = 5.0                # s read again before the last read (revocations)
CREATED_MARGIN = 60.0             # s (sessions are stamped with their gateway's clock)

HOLDS = sa.Table(
    'fleet_holds', METADATA,
    sa.Column('kind', sa.String(16), primary_key=True),
    sa.Column('name', sa.String(200), primary_key=True),
    sa.Column('person', sa.String(200), nullable=False),
    sa.Column('who', sa.String(300), nullable=False),
    sa.Column('gateway', sa.String(32), nullable=False),
    sa.Column('expires', sa.Float, nullable=False),
)
STATE = sa.Table(
    'fleet_state', METADATA,
    sa.Column('kind', sa.String(16), primary_key=True),
    sa.Column('name', sa.String(200), primary_key=True),
    sa.Column('value', sa.Text, nullable=False),
    sa.Column('gateway', sa.String(32), nullable=False),
    sa.Column('at', sa.Float, nullable=False),
    sa.Column('until', sa.Float, nullable=True),
)
GATEWAYS = sa.Table(
    'fleet_gateways', METADATA,
    sa.Column('id', sa.String(32), primary_key=True),
    sa.Column('expires', sa.Float, nullable=False),
    sa.Column('seen', sa.Float, nullable=False),
    sa.Column('started', sa.Float, nullable=False),
)
NOW = sa.literal_column('extract(epoch from clock_timestamp())', sa.Float)   # the database's clock, one for all
UNREAD = ('revoked', 'once')      # state kinds read only since the last read (or never)


def lost_connection(e: BaseException) -> bool:
    """Whether a failure is the database's absence (retry), not a statement's fault."""
    return isinstance(e, (sa.exc.OperationalError, sa.exc.InterfaceError)) or (
        isinstance(e, sa.exc.DBAPIError) and e.connection_invalidated)


@dataclass
class Job:
    """fn(connection) in a transaction on the worker; ``done(result, error)`` on the loop.
    ``retry``: tried again until the database takes it (else one try); ``after(connection)``: read
    in a second transaction once the first committed (its result is handed on with the first's)."""
    fn: Callable[[sa.Connection], Any]
    done: Callable[[Any, BaseException | None], None] | None = None
    retry: bool = True
    after: Callable[[sa.Connection], Any] | None = None
    dropped: bool = False            # nobody waits for it any more: not run if not begun
    seq: int = 0


@dataclass
class Read:
    """One beat's read of the shared state, handed to the loop."""
    started: float                   # time.monotonic() before the transaction began
    clock: float                     # the database's clock at the read
    written: int                     # the last job seq written before it
    lost: list                       # [(kind, name)] of this gateway's holds it no longer has
    holds: list                      # live rows of fleet_holds, with 'left' (s)
    state: list                      # rows of fleet_state
    extra: dict = field(default_factory=dict)   # each reader's data, by name


class Worker:
    """The fleet's database thread and its LISTEN thread (see the module docstring)."""

    def __init__(self, store, gateway: str, post: Callable[..., None], heard: Callable[[str], None],
                 read: Callable[[Read], None]):
        """post(fn, *args): call fn on the loop; heard(payload): a notification; read(Read): a beat's read."""
        self.store, self.id, self.post, self.heard, self.read = store, gateway, post, heard, read
        url = store.engine.url
        self.engine = sa.create_engine(url, pool_size=2, max_overflow=2, pool_pre_ping=True,
                                       connect_args=connect_args('fleet'))
        self._dsn = url.set(drivername='postgresql').render_as_string(hide_password=False)
        self.jobs: queue.SimpleQueue = queue.SimpleQueue()
        self.held: set[tuple[str, str]] = set()        # our holds as written (this thread's)
        self.readers: dict[str, Callable[[sa.Connection, float], Any]] = {}
        self.applied = 0.0           # the database's clock of the last read the loop applied (for 'seen')
        self.since = 0.0             # the database's clock of the last read
        self.timekeeper = False
        self.notified = 0
        self._seq = 0
        self._beat_now = threading.Event()
        self._closing = threading.Event()
        self._threads: list[threading.Thread] = []

    # --- asked from the loop --------------------------------------------------------------------

    def submit(self, job: Job) -> Job:
        self._seq += 1
        job.seq = self._seq
        self.jobs.put(job)
        return job

    def beat_now(self) -> None:
        self._beat_now.set()
        self.jobs.put(None)

    def run_now(self, fn):
        with self.engine.begin() as c:
            return fn(c)

    def start(self) -> None:
        for target, name in ((self._listen, 'rosgate-fleet-listen'), (self._work, 'rosgate-fleet')):
            t = threading.Thread(target=target, name=name, daemon=True)
            t.start()
            self._threads.append(t)

    def close(self) -> None:
        self._closing.set()
        self.jobs.put('close')
        for t in self._threads:
            t.join(timeout=3)
        self.engine.dispose()

    # --- statements -----------------------------------------------------------------------------

    def send(self, c: sa.Connection, what: str, **event) -> None:
        event.update(ev=what, gw=self.id)
        c.execute(sa.select(sa.func.pg_notify(CHANNEL, json.dumps(event))))
        self.notified += 1

    def insert_hold(self, c, kind: str, name: str, person: str, who: str, force: bool = False):
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
        self.held.add((kind, name))
        self.send(c, 'hold', k=kind, name=name, person=person, who=who, force=force)
        return None

    def drop_hold(self, c, kind: str, name: str) -> None:
        c.execute(HOLDS.delete().where(HOLDS.c.kind == kind, HOLDS.c.name == name, HOLDS.c.gateway == self.id))
        self.held.discard((kind, name))
        self.send(c, 'drop', k=kind, name=name)

    def end_holds(self, c, ends, why: str | None = None) -> None:
        """Whoever's holds ``ends`` [(kind, name)] are, they end (a Stop, a Release; ``why`` for
        the holder's clients)."""
        for kind, name in ends:
            c.execute(HOLDS.delete().where(HOLDS.c.kind == kind, HOLDS.c.name == name))
            self.held.discard((kind, name))
            self.send(c, 'end', k=kind, name=name, why=why)

    @staticmethod
    def lock_group(c, name: str) -> None:
        c.execute(sa.select(sa.func.pg_advisory_xact_lock(LEASE_KEY, sa.func.hashtext(name))))

    def write_state(self, c, kind: str, name: str, value: dict | None, until: float | None, seq: int = 0) -> None:
        from sqlalchemy.dialects.postgresql import insert
        if value is None:
            c.execute(STATE.delete().where(STATE.c.kind == kind, STATE.c.name == name))
        else:
            stmt = insert(STATE).values(kind=kind, name=name, value=json.dumps(value), gateway=self.id, at=NOW,
                                        until=until)
            c.execute(stmt.on_conflict_do_update(index_elements=['kind', 'name'], set_=dict(
                value=stmt.excluded.value, gateway=stmt.excluded.gateway, at=stmt.excluded.at,
                until=stmt.excluded.until)))
        self.send(c, 'state', k=kind, name=name, value=value, gateway=self.id, seq=seq)

    def unbar(self, c, station: str, person: str, seq: int) -> list[str]:
        """A person claims a station: the teacher's Releases that barred her (from it, or anyone from
        it) are behind her, in the same transaction (rules.stations); the stations unbarred."""
        rows = c.execute(sa.select(STATE.c.name, STATE.c.value).where(STATE.c.kind == 'bar')).all()
        gone = {r.name for r in rows if json.loads(r.value).get('person') == person} | {station}
        for name in sorted(gone):    # the station's, always: its notice tells this gateway it is written
            self.write_state(c, 'bar', name, None, None, seq)
        return sorted(gone)

    def once(self, c, name: str) -> bool:
        """Whether this gateway is the first to claim ``name`` (kept a day)."""
        from sqlalchemy.dialects.postgresql import insert
        return c.execute(insert(STATE).values(kind='once', name=name[:200], value='{}', gateway=self.id, at=NOW,
                                              until=NOW + 86400)
                         .on_conflict_do_nothing().returning(STATE.c.name)).first() is not None

    def stop_row(self, c, group: str):
        return c.execute(sa.select(STATE.c.value).where(STATE.c.kind == 'stop', STATE.c.name == group)).first()

    def gateways(self, c) -> dict[str, tuple[float, float]]:
        """The other live gateways: id -> (seen, seconds left), and the clock now (key None)."""
        rows = c.execute(sa.select(GATEWAYS.c.id, GATEWAYS.c.seen, (GATEWAYS.c.expires - NOW).label('left'))
                         .where(GATEWAYS.c.expires > NOW, GATEWAYS.c.id != self.id)).all()
        found = {r.id: (r.seen, r.left) for r in rows}
        found[None] = (c.execute(sa.select(NOW)).scalar(), 0.0)
        return found

    def _beat(self, c, started: float, written: int) -> Read:
        from sqlalchemy.dialects.postgresql import insert
        clock = c.execute(sa.select(NOW)).scalar()
        stmt = insert(GATEWAYS).values(id=self.id, expires=NOW + HOLD, seen=self.applied, started=NOW)
        c.execute(stmt.on_conflict_do_update(index_elements=['id'], set_=dict(
            expires=stmt.excluded.expires, seen=stmt.excluded.seen)))
        # a lease lives on only while its row did (a gateway away longer than HOLD lost it); a
        # claim is kept as long as nobody else took it (a student keeps her station through a blip)
        kept = c.execute(sa.update(HOLDS).where(HOLDS.c.gateway == self.id,
                                                (HOLDS.c.kind != 'lease') | (HOLDS.c.expires > NOW))
                         .values(expires=NOW + HOLD).returning(HOLDS.c.kind, HOLDS.c.name)).all()
        kept = {(r.kind, r.name) for r in kept}
        lost = sorted(self.held - kept)
        self.held &= kept
        if lost:
            c.execute(HOLDS.delete().where(HOLDS.c.gateway == self.id, HOLDS.c.expires <= NOW))
        holds = c.execute(sa.select(HOLDS, (HOLDS.c.expires - NOW).label('left'))
                          .where(HOLDS.c.expires > NOW)).all()
        since = (self.since or clock) - SINCE_MARGIN
        state = c.execute(sa.select(STATE).where(STATE.c.kind.not_in(UNREAD)
                                                 | ((STATE.c.kind == 'revoked') & (STATE.c.at > since)))).all()
        extra = {name: fn(c, (self.since or clock) - CREATED_MARGIN) for name, fn in self.readers.items()}
        if self.timekeeper:   # the fleet's housekeeping, once
            c.execute(HOLDS.delete().where(HOLDS.c.expires < NOW - 60))
            c.execute(STATE.delete().where(STATE.c.until < NOW))
            live = sa.select(GATEWAYS.c.id).where(GATEWAYS.c.expires > NOW)
            c.execute(STATE.delete().where(STATE.c.kind == 'queue', STATE.c.gateway.not_in(live)))
            c.execute(GATEWAYS.delete().where(GATEWAYS.c.expires < NOW - 3600))
        self.since = clock
        return Read(started, clock, written, lost, holds, state, extra)

    # --- the threads ----------------------------------------------------------------------------

    def _listen(self) -> None:
        import psycopg
        tries = 0
        while not self._closing.is_set():
            try:
                with psycopg.connect(self._dsn, autocommit=True, **connect_args('listen')) as conn:
                    conn.execute(f'LISTEN {CHANNEL}')
                    if tries:
                        log.info('fleet: listening again; reading the shared state')
                    tries = 0
                    self.beat_now()      # what was notified while we did not listen is read now
                    while not self._closing.is_set():
                        for n in conn.notifies(timeout=0.5):
                            self.post(self.heard, n.payload)
            except Exception as e:
                if not self._closing.is_set():
                    if tries == 0:
                        log.warning('fleet: listening failed (%s); trying again', e)
                    self._closing.wait(RETRY[min(tries, len(RETRY) - 1)])
                    tries += 1

    def _keep_time(self, lock):
        """The timekeeper's advisory lock, tried (or checked) each beat; the lock's connection."""
        import psycopg
        if lock is None or lock.closed:
            lock = psycopg.connect(self._dsn, autocommit=True, **connect_args('lock'))
            self.timekeeper = False
        if self.timekeeper:
            lock.execute('SELECT 1')       # a killed connection took the lock with it: we learn it here
        else:
            self.timekeeper = bool(lock.execute('SELECT pg_try_advisory_lock(%s)', (TIMEKEEPER_KEY,)).fetchone()[0])
            if self.timekeeper:
                log.info('fleet: this gateway keeps time (slot resets, history)')
        return lock

    def _work(self) -> None:
        """Jobs in order (writes retried until taken); every BEAT the rows refreshed and the state read."""
        lock = None
        next_beat = 0.0
        job = None
        tries = 0
        written = 0
        while True:
            if job is None:
                try:
                    job = self.jobs.get(timeout=max(0.0, next_beat - time.monotonic()))
                except queue.Empty:
                    job = None
            if job == 'close':
                break
            try:
                if job is not None and not job.dropped:
                    with self.engine.begin() as c:
                        result = job.fn(c)
                    if job.after is not None:
                        with self.engine.begin() as c:
                            result = (result, job.after(c))
                    if job.done is not None:
                        self.post(job.done, result, None)
                if job is not None:
                    written = job.seq
                job = None
                if time.monotonic() >= next_beat or self._beat_now.is_set():
                    self._beat_now.clear()
                    try:
                        lock = self._keep_time(lock)
                    except Exception as e:
                        log.warning('fleet: the timekeeper\'s lock: %s', e)
                        self.timekeeper = False
                        if lock is not None:
                            lock.close()
                        lock = None
                    started = time.monotonic()
                    with self.engine.begin() as c:
                        read = self._beat(c, started, written)
                    next_beat = started + BEAT
                    self.post(self.read, read)
                if tries:
                    log.info('fleet: the database answers again')
                tries = 0
            except Exception as e:
                if job is not None and not (job.retry and lost_connection(e)):
                    if not lost_connection(e):
                        log.exception('fleet: a write failed')
                    if job.done is not None:
                        self.post(job.done, None, e)
                    job = None
                if tries == 0:
                    log.warning('fleet: the database does not answer (%s); trying again',
                                str(e).splitlines()[0] if str(e) else type(e).__name__)
                self._closing.wait(RETRY[min(tries, len(RETRY) - 1)])
                tries += 1
        if lock is not None:
            lock.close()
        try:
            with self.engine.begin() as c:
                c.execute(HOLDS.delete().where(HOLDS.c.gateway == self.id))
                c.execute(GATEWAYS.delete().where(GATEWAYS.c.id == self.id))
        except Exception:
            pass
