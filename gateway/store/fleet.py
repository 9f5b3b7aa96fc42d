"""A fleet of gateways on one PostgreSQL (``--db postgresql+psycopg://…`` on each): what they share.

One gateway is one tornado process on one core; a lab of several classes runs several behind one
proxy, on one ROS graph. What must hold across them is *state in PostgreSQL* (``store.fleetdb``),
settled by PostgreSQL's own mechanisms, no consensus of ours:

- *holds*: a station's claim, a group's driver lease; a row per (kind, name) naming the person,
  who (for refusals) and the gateway, alive while its gateway beats (HOLD s past the last beat).
  Taking one is one ``INSERT … ON CONFLICT DO UPDATE … WHERE``: two gateways taking one hold at
  once get one yes and one no naming the holder. ``take`` waits for that word (a claim, a free
  lease's first command); ``hold`` writes through without waiting (the same person's hold again,
  an admin's takeover).
- *state*: a Stop in force, a teacher's Release, a place in the walk-in line, a signed-out session,
  a slot's reset done once (``put``, ``remove``, ``state``; rules.fleet says what each means).
- NOTIFY only wakes: a change is written, then told; each gateway mirrors holds and state in
  memory and reads them all back every BEAT and whenever its LISTEN connection (re)connects, so
  a Stop or a logout sent while a gateway could not hear is applied when it can, and a gateway
  started later knows every Stop in force. What changed here or was heard after a read began
  is not undone by that read.
- *confirmation*: the mirror is trusted for HOLD - MARGIN s after the beat that last read it. Past
  that (``confirmed()`` false) the gateway cannot know what the others did: the rules take no new
  lease, end the leases they hold (their rows lapse then anyway) and refuse sign-ins (a logout
  elsewhere waits for every live gateway's word, or for its row to lapse: ``everywhere``).
- the *timekeeper* (an advisory lock): one gateway writes the history; one-off deeds (a station's
  reset at a slot's end) are claimed as rows (``once``).

The rules never wait on the database on the publish path: ``held`` and ``state`` are dicts.
Only a PostgreSQL store makes a fleet (``Fleet.of``); SQLite is one gateway, as before.
May import: ``settings`` and ``store``.
"""

from __future__ import annotations

import asyncio
import json
import logging
import secrets
import time
from dataclasses import dataclass
from typing import Any, Callable, Protocol

import sqlalchemy as sa

from .fleetdb import BEAT, BOOKING_KEY, HOLD, HOLDS, STATE, Job, Read, Worker   # noqa: F401 (tables: tests)

log = logging.getLogger('rosgate.fleet')
MARGIN = 0.5          # s before its rows would lapse that a gateway stops trusting its mirror
TAKE_TIMEOUT = 3.0    # s a first command waits for PostgreSQL's word at most
WATCH = 0.2           # s between looks at the confirmation
WAIT_LIMIT = 10.0     # s a logout waits for the other gateways at most


class Unreachable(Exception):
    """The database cannot settle it now; the message says since when (safe to show)."""


@dataclass
class Hold:
    person: str
    who: str
    gateway: str
    until: float     # time.monotonic() past which it no longer holds


@dataclass
class Stopped:
    """A lease not taken: the group's Stop is in force (by whom)."""
    by: str


class FleetListener(Protocol):
    """What the fleet tells the rules (``rules.fleet.FleetPart``), one typed method per event, on
    the loop; given once to ``Fleet.start`` (the store may not import ``rules.hooks``)."""
    def on_event(self, what: str, event: dict) -> None: ...                      # another gateway's notice
    def on_state_changed(self, kind: str, name: str, old: dict | None, new: dict | None) -> None: ...
    def on_hold_lost(self, kind: str, name: str, holder: Hold | None, why: str | None) -> None: ...
    def on_hold_lapsed(self, kind: str, name: str, holder: Hold) -> None: ...   # its gateway died
    def on_read(self, name: str, data: Any) -> None: ...                       # a reader's result, each beat
    def on_cut_off(self) -> None: ...          # confirmation lapsed (once)
    def on_back(self) -> None: ...             # and returned


Reader = Callable[[sa.Connection, float], Any]   # read(connection, since): its result to ``on_read``


def clock(at: float) -> str:
    return time.strftime('%H:%M:%S', time.localtime(at))


class Fleet:
    """This gateway's part in the fleet: its holds, the others' (mirrored), the shared state."""

    @classmethod
    def of(cls, store) -> 'Fleet | None':
        return cls(store) if store.engine.dialect.name == 'postgresql' else None

    def __init__(self, store):
        self.store, self.id = store, secrets.token_hex(6)
        self.mine: dict[tuple[str, str], tuple[str, str]] = {}   # (kind, name) -> (person, who)
        self.others: dict[tuple[str, str], Hold] = {}
        self.heard: dict[tuple[str, str], float] = {}   # when an event last changed a hold (monotonic)
        self.values: dict[tuple[str, str], dict] = {}            # the shared state: (kind, name) -> value
        self.listener: FleetListener | None = None               # the rules (``start``)
        self.booking_key = BOOKING_KEY
        self.confirmed_until = 0.0
        self.unreachable = None          # time.time() since when the mirror is not confirmed (None: it is)
        self._touched: dict[tuple[str, str], int] = {}    # state changed here: the job's seq
        self._holding: dict[tuple[str, str], int] = {}    # holds asked here: the job's seq
        self._state_heard: dict[tuple[str, str], float] = {}
        self._acks: dict[tuple[str, str], set[str]] = {}
        self._loop: asyncio.AbstractEventLoop | None = None
        self._timer: asyncio.TimerHandle | None = None
        self.db = Worker(store, self.id, self._post, self._heard, self._read)

    @property
    def timekeeper(self) -> bool:
        return self.db.timekeeper

    @property
    def notified(self) -> int:
        return self.db.notified

    # --- on the loop --------------------------------------------------------------------------

    def start(self, loop: asyncio.AbstractEventLoop, listener: FleetListener,
              readers: dict[str, Reader] | None = None) -> None:
        """The shared state read once before the first client (a Stop in force holds at once).
        ``listener`` hears every change, event and loss; ``readers``: name -> read(connection, since),
        run at each beat (since: the database's clock, a margin before the last read) on the fleet's
        thread, what it read told to ``listener.on_read(name, data)`` on the loop."""
        if self._loop is not None:
            raise RuntimeError('the fleet is started once')
        self._loop, self.listener = loop, listener
        self.db.readers.update(readers or {})
        started = time.monotonic()
        self._read(self.db.run_now(lambda c: self.db._beat(c, started, 0)), first=True)
        self.db.start()
        self._timer = loop.call_later(WATCH, self._watch)
        log.info('fleet: gateway %s on %s', self.id, self.store.url)

    def confirmed(self) -> bool:
        return time.monotonic() < self.confirmed_until

    def why_unconfirmed(self) -> str:
        since = clock(self.unreachable) if self.unreachable else 'a moment ago'
        return f'this gateway has not reached its database since {since}'

    def _watch(self) -> None:
        if self.unreachable is None and not self.confirmed():
            self.unreachable = time.time() - max(0.0, time.monotonic() - self.confirmed_until + HOLD - MARGIN)
            log.warning('fleet: %s; its leases end and no new one is taken until it does', self.why_unconfirmed())
            self._tell('on_cut_off')
        if self._loop is not None and not self._loop.is_closed():
            self._timer = self._loop.call_later(WATCH, self._watch)

    def _tell(self, event: str, *args) -> None:
        """The listener's ``event(*args)``; one that raises is logged, the fleet carries on."""
        if self.listener is None:
            return
        try:
            getattr(self.listener, event)(*args)
        except Exception:
            log.exception('fleet: %s of %s failed', event, type(self.listener).__name__)

    # --- holds ----------------------------------------------------------------------------------

    def held(self, kind: str, name: str) -> Hold | None:
        """Who holds (kind, name) through another gateway now, or None: a dict lookup."""
        h = self.others.get((kind, name))
        return h if h is not None and h.until > time.monotonic() else None

    def holds(self, kind: str, name: str, person: str) -> bool:
        """Whether this gateway holds (kind, name) for ``person`` (PostgreSQL said so)."""
        mine = self.mine.get((kind, name))
        return mine is not None and mine[0] == person

    def hold(self, kind: str, name: str, person: str, who: str, force: bool = False) -> None:
        """Take (or keep) a hold without waiting; the others hear it. ``force``: over anyone's."""
        key = (kind, name)
        if self.mine.get(key) == (person, who) and not force:
            return
        self.mine[key] = (person, who)
        self.others.pop(key, None)

        def done(theirs, error):
            if theirs is not None and error is None:
                self._lost_hold(kind, name, person, who, theirs)
        job = self.db.submit(Job(lambda c: self.db.insert_hold(c, kind, name, person, who, force), done))
        self._holding[key] = job.seq

    async def take(self, kind: str, name: str, person: str, who: str) -> Hold | Stopped | None:
        """Take a hold and wait for PostgreSQL's word: None when it is this gateway's, else who
        holds it (or, for a lease, the Stop that holds its group). One transaction, in order with
        this gateway's writes, off the loop; Unreachable when the database cannot answer now."""
        if not self.confirmed():
            raise Unreachable(self.why_unconfirmed())
        future = self._loop.create_future()

        def run(c):
            if kind == 'lease':       # one at a time with a Stop of the group (fleetdb.lock_group)
                self.db.lock_group(c, name)
                stop = self.db.stop_row(c, name)
                if stop is not None:
                    return Stopped(json.loads(stop.value).get('by', 'the teacher'))
            theirs = self.db.insert_hold(c, kind, name, person, who)
            if theirs is None and kind == 'claim':   # she claims: a Release that barred her is behind her
                self.db.unbar(c, name, person, job.seq)
            return theirs

        def done(result, error):
            if future.done():         # too late: nobody waits; a hold taken meanwhile goes back
                if error is None and result is None and self.mine.get((kind, name), (None,))[0] != person:
                    self.db.submit(Job(lambda c: self.db.drop_hold(c, kind, name)))
                return
            if error is not None:
                future.set_exception(Unreachable(f'the database did not answer ({type(error).__name__})'))
            else:
                future.set_result(result)
        job = self.db.submit(Job(run, done, retry=False))
        self._holding[(kind, name)] = job.seq
        if kind == 'claim':
            self._touched[('bar', name)] = job.seq
        try:
            theirs = await asyncio.wait_for(asyncio.shield(future), TAKE_TIMEOUT)
        except asyncio.TimeoutError:
            job.dropped = True
            future.cancel()
            raise Unreachable(f'the database did not answer within {TAKE_TIMEOUT:g} s') from None
        key = (kind, name)
        if theirs is None:
            self.mine[key] = (person, who)
            self.others.pop(key, None)
            return None
        if isinstance(theirs, Stopped):
            return theirs
        if self.mine.get(key, (None,))[0] == person:
            del self.mine[key]        # what ``hold`` queued for it loses quietly: the caller answers
        holder = Hold(theirs.person, theirs.who, theirs.gateway, time.monotonic() + HOLD)
        self.others[key] = holder
        return holder

    def drop(self, kind: str, name: str) -> None:
        if self.mine.pop((kind, name), None) is not None:
            self.db.submit(Job(lambda c: self.db.drop_hold(c, kind, name)))

    def write(self, fn: Callable[[sa.Connection], Any]) -> None:
        """fn(connection) on the fleet's thread, in order with its other writes, retried until taken."""
        self.db.submit(Job(fn))

    def end(self, kind: str, name: str, why: str | None = None) -> None:
        """Whoever's hold (kind, name) is, through any gateway, it ends (its holder's clients told ``why``)."""
        self.others.pop((kind, name), None)
        self.mine.pop((kind, name), None)
        self.db.submit(Job(lambda c: self.db.end_holds(c, [(kind, name)], why)))

    def notify(self, what: str, **event) -> None:
        """Tell the other gateways (``on(what, fn)`` there hears it): a wake-up, not state."""
        self.db.submit(Job(lambda c: self.db.send(c, what, **event)))

    def _lose(self, key: tuple[str, str], holder: Hold | None, why: str | None = None) -> None:
        """Our hold is gone: ``holder`` has it now, or nobody (ended elsewhere: ``why``, or lapsed)."""
        self._tell('on_hold_lost', key[0], key[1], holder, why)

    def _lost_hold(self, kind: str, name: str, person: str, who: str, row) -> None:
        """Our INSERT found the hold someone else's (both took it at once): we give way."""
        holder = Hold(row.person, row.who, row.gateway, time.monotonic() + HOLD)
        self.others[(kind, name)] = holder
        if self.mine.get((kind, name)) == (person, who):
            del self.mine[(kind, name)]
            self._lose((kind, name), holder)

    # --- shared state ---------------------------------------------------------------------------

    def state(self, kind: str) -> dict[str, dict]:
        return {name: v for (k, name), v in self.values.items() if k == kind}

    def put(self, kind: str, name: str, value: dict | None, *, until: float | None = None, ends=(),
            why: str | None = None, also: Callable[[sa.Connection], None] | None = None,
            after=None) -> asyncio.Future:
        """State changed here (value None: removed): mirrored at once, written (retried until the
        database takes it), then told. ``ends``: holds [(kind, name)] of any gateway ended in the
        same transaction, after the row (their holders' clients are told ``why``); ``also(connection)``:
        more in it; ``after(connection)``: read once it committed. The future (may be ignored)
        resolves with (None, after's result) when committed."""
        key = (kind, name)
        if value is None:
            self.values.pop(key, None)
        else:
            self.values[key] = {**value, 'gateway': self.id}
        future = self._loop.create_future() if self._loop is not None else None

        def run(c):
            if kind == 'stop' or ends:
                self.db.lock_group(c, name)
            self.db.write_state(c, kind, name, value, until, job.seq)
            self.db.end_holds(c, ends, why)
            if also is not None:
                also(c)

        job = Job(run, _settles(future) if future is not None else None, after=after)
        self.db.submit(job)
        self._touched[key] = job.seq
        for end in ends:             # the caller has let go of its own already
            self.others.pop(end, None)
            self.mine.pop(end, None)
        return future

    def remove(self, kind: str, name: str, **kw) -> asyncio.Future:
        return self.put(kind, name, None, **kw)

    def _apply_state(self, kind: str, name: str, value: dict | None) -> None:
        key = (kind, name)
        old = self.values.get(key)
        if old == value:
            return
        if value is None:
            del self.values[key]
        else:
            self.values[key] = value
        self._tell('on_state_changed', kind, name, old, value)

    def ack(self, kind: str, name: str) -> None:
        """Tell the gateway that wrote it that this one applied (kind, name) (a logout)."""
        self.notify('ack', k=kind, name=name)

    async def everywhere(self, committed, kind: str, name: str) -> list[str]:
        """After ``put``'s future resolved (``after=self.db.gateways``): wait until every gateway
        alive then has applied (kind, name) (its ack, or its ``seen`` past the commit) or lapsed
        (its rows gone: it stopped trusting its mirror before that). Returns those that never said."""
        _, found = committed
        at = found.pop(None)[0]
        waiting = {gw for gw, (seen, left) in found.items() if seen < at}
        acks, woken = self._acks.setdefault((kind, name), (set(), asyncio.Event()))
        deadline = time.monotonic() + WAIT_LIMIT
        try:
            while waiting and time.monotonic() < deadline:
                try:
                    await asyncio.wait_for(woken.wait(), 0.2)
                except asyncio.TimeoutError:   # no word: their rows say whether they saw it or lapsed
                    future = self._loop.create_future()
                    self.db.submit(Job(self.db.gateways, _settles(future), retry=False))
                    try:
                        rows = await future
                    except Exception:
                        rows = None
                    if rows is not None:
                        waiting = {gw for gw in waiting if gw in rows and rows[gw][0] < at}
                woken.clear()
                waiting -= acks
        finally:
            self._acks.pop((kind, name), None)
        return sorted(waiting)

    # --- what the database and the other gateways say ---------------------------------------------

    def _post(self, fn, *args) -> None:
        if self._loop is not None and not self._loop.is_closed():
            self._loop.call_soon_threadsafe(fn, *args)

    def _heard(self, payload: str) -> None:
        try:
            event = json.loads(payload)
        except ValueError:
            return
        what = event.get('ev')
        if event.get('gw') == self.id:
            if what == 'state':      # our own write, committed: the others' notices on it count again
                key = (event['k'], event['name'])
                if self._touched.get(key, 0) <= event.get('seq', 0):
                    self._touched.pop(key, None)
            return
        now = time.monotonic()
        if what in ('hold', 'drop', 'end'):
            key = (event['k'], event['name'])
            self.heard[key] = now
            if what == 'hold':
                self.others[key] = Hold(event['person'], event['who'], event['gw'], now + HOLD)
                if key in self.mine and (self.mine[key][0] != event['person'] or event.get('force')):
                    self.mine.pop(key)
                    self._lose(key, self.others[key])
            elif what == 'drop':
                h = self.others.get(key)
                if h is not None and h.gateway == event['gw']:
                    del self.others[key]
            else:                        # ended by another gateway (a Stop, a Release), whoever held it
                self.others.pop(key, None)
                if self.mine.pop(key, None) is not None:
                    self._lose(key, None, event.get('why'))
        elif what == 'state':
            key = (event['k'], event['name'])
            if key in self._touched:     # older than our write not yet committed: that decides (or a read)
                return
            self._state_heard[key] = now
            value = event.get('value')
            self._apply_state(key[0], key[1], None if value is None else {**value, 'gateway': event['gateway']})
        elif what == 'ack':
            waiting = self._acks.get((event['k'], event['name']))
            if waiting is not None:
                waiting[0].add(event['gw'])
                waiting[1].set()
        if what is not None:
            self._tell('on_event', what, event)

    def _read(self, read: Read, first: bool = False) -> None:
        """A beat's read of the shared state: the mirror brought to it, except what changed here
        since (not yet written when it was read) or was heard after it began."""
        now = time.monotonic()
        for key in read.lost:            # our holds the database no longer has: expired, ended, taken
            if self._holding.get(key, 0) > read.written or self.heard.get(key, 0) >= read.started:
                continue                 # asked again since, or heard of since: that decides
            if self.mine.pop(key, None) is not None:
                row = next((r for r in read.holds if (r.kind, r.name) == key), None)
                self._lose(key, None if row is None else Hold(row.person, row.who, row.gateway, now + row.left))
        for key in [k for k, seq in self._holding.items() if seq <= read.written]:
            del self._holding[key]
        self._read_holds(read, now)
        rows = {(r.kind, r.name): r for r in read.state}
        for key in set(rows) | {k for k in self.values if k[0] != 'revoked'}:
            if self._touched.get(key, 0) > read.written or self._state_heard.get(key, 0) >= read.started:
                continue
            r = rows.get(key)
            self._apply_state(key[0], key[1], None if r is None else {**json.loads(r.value), 'gateway': r.gateway})
        for key in [k for k, seq in self._touched.items() if seq <= read.written]:
            del self._touched[key]
        for key in [k for k, v in self.values.items() if k[0] == 'revoked' and v.get('until', 0) < time.time()]:
            del self.values[key]
        for key in [k for k, at in self._state_heard.items() if at < now - 60]:
            del self._state_heard[key]
        for name, data in read.extra.items():
            self._tell('on_read', name, data)
        was_cut = self.unreachable is not None
        self.confirmed_until = read.started + HOLD - MARGIN
        self.unreachable = None
        self.db.applied = read.clock
        if was_cut and not first:
            log.info('fleet: the database answers again; the shared state is read')
            self._tell('on_back')

    def _read_holds(self, read: Read, now: float) -> None:
        seen = {}
        for r in read.holds:
            if r.gateway != self.id:
                seen[(r.kind, r.name)] = Hold(r.person, r.who, r.gateway, now + r.left)
        for key, at in list(self.heard.items()):
            if at >= read.started:
                seen.pop(key, None)
                if key in self.others:
                    seen[key] = self.others[key]
            elif at < now - 60:
                del self.heard[key]
        gone = [(key, h) for key, h in self.others.items() if key not in seen]
        self.others = seen
        for (kind, name), h in gone:   # not given back (that is an event): it lapsed, its gateway is gone
            self._tell('on_hold_lapsed', kind, name, h)

    async def once(self, name: str, within: float = 30.0) -> bool:
        """Whether this gateway is the one to do ``name`` (a row only one gateway inserts); waits
        for the database up to ``within`` s (False then: someone else may have)."""
        future = self._loop.create_future()
        job = self.db.submit(Job(lambda c: self.db.once(c, name), _settles(future)))
        try:
            return await asyncio.wait_for(asyncio.shield(future), within)
        except Exception as e:
            job.dropped = True
            log.warning('fleet: %s not settled with the database (%s)', name, str(e) or type(e).__name__)
            return False

    def close(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self.db.close()


def _settles(future: asyncio.Future) -> Callable[[Any, BaseException | None], None]:
    """A Job's ``done`` that settles ``future`` (unless nobody waits for it any more)."""
    def done(result, error):
        if not future.done():
            future.set_exception(error) if error is not None else future.set_result(result)
    return done
