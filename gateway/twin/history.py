"""History: the numeric fields of chosen topics, kept by the gateway whether or not a page is open.

An operator at a distance needs the robot's past as well as its present (is there charge enough
to get back?), and a browser keeps nothing once it is closed. So the gateway itself is one more
subscriber of each kept topic's shared fan-out (no second backend subscription), at most about
once a second per topic (the fan-out's own ``throttle_rate`` keeps the latest message), and writes
each numeric field as a point through the one store:

- ``history_points``: full rate (1 Hz) for the recent ``--history-full-hours`` (a day by default);
- ``history_minutes``: older points rolled up into per-minute count/min/mean/max, once a minute;
- ``--history-max-mb``: past this many megabytes in use, the oldest tenth of the kept time goes.

Points wait in a list on the event loop and go to the store's thread as one batch every
``FLUSH`` seconds (one transaction, one fsync at most), so the loop never waits on the disk.

Which topics: ``--history GLOBS`` (topic names), or by default every topic of a type the
dashboards and the world view show (``DEFAULT_TYPES``: battery, temperatures, odometry, a turtle's pose); ``--history none`` keeps
nothing. Only topics the name globs let a client subscribe to are kept, and only while something
publishes them: ROS 2 lists a topic that only has subscribers (a page looking for /odom on a
turtle), and the history's own subscription would keep such a name listed for ever. The reading side
is ``queries`` (``/api/history``: ``web.history``).
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import math
import time
from collections import deque
from fnmatch import fnmatchcase

import orjson
import sqlalchemy as sa

from ..rules.access import may
from ..rules.names import parse_globs
from ..settings import TwinSettings
from ..store import METADATA
from ..rules.hooks import Hook
from .ports import Graph, Names, Points, Store, Taps, Timekeeper

log = logging.getLogger('rosgate.history')

SERIES = sa.Table(
    'history_series', METADATA,
    sa.Column('id', sa.Integer, primary_key=True),
    sa.Column('topic', sa.String(255), nullable=False),
    sa.Column('field', sa.String(255), nullable=False),
    sa.UniqueConstraint('topic', 'field', name='history_series_topic_field'))
POINTS = sa.Table(   # full rate; t in ms since the epoch (integers divide alike in SQLite and PostgreSQL)
    'history_points', METADATA,
    sa.Column('series', sa.Integer, nullable=False),
    sa.Column('t', sa.BigInteger, nullable=False),
    sa.Column('v', sa.Float, nullable=False),
    # one series' span is one range of the key, its rows side by side on disk (SQLite: no rowid,
    # the table is the key's b-tree): a day of one field read 3x faster than through an index
    sa.PrimaryKeyConstraint('series', 't', name='history_points_pk'),
    sqlite_with_rowid=False)
MINUTES = sa.Table(  # t: the minute's start, ms
    'history_minutes', METADATA,
    sa.Column('series', sa.Integer, nullable=False),
    sa.Column('t', sa.BigInteger, nullable=False),
    sa.Column('n', sa.Integer, nullable=False),
    sa.Column('vmin', sa.Float, nullable=False),
    sa.Column('vmean', sa.Float, nullable=False),
    sa.Column('vmax', sa.Float, nullable=False),
    sa.Index('history_minutes_series_t', 'series', 't'))

# The fields kept of the types the dashboards show; other types: their numeric scalars.
KNOWN_FIELDS = {
    'sensor_msgs/msg/BatteryState': ('percentage', 'voltage', 'current', 'charge', 'temperature'),
    'sensor_msgs/msg/Temperature': ('temperature',),
    'nav_msgs/msg/Odometry': ('twist.twist.linear.x', 'twist.twist.angular.z',
                              'pose.pose.position.x', 'pose.pose.position.y', 'yaw'),
    'turtlesim/msg/Pose': ('x', 'y', 'theta', 'linear_velocity', 'angular_velocity'),
}
DEFAULT_TYPES = tuple(KNOWN_FIELDS)
MAX_FIELDS = 16             # of a type not in KNOWN_FIELDS
THROTTLE_MS = 950           # the fan-out hands over at most one message per topic this often (about 1 Hz)
MIN_GAP = 0.9               # s between two points of one series
FLUSH = 2.0                 # s between batches to the store
POLL = 2.0                  # s between looks for new topics to keep
COMPACT_EVERY = 60.0        # s between roll-ups (and size checks)
REPORT_EVERY = 600.0        # s between lines in the log saying rows/s and size
MINUTE = 60_000             # ms
_tap_ids = itertools.count(-1_000_000, -1)   # fan-out keys: negative, never a client's (recordings count from -1)


def field_value(msg: dict, path: str):
    """A number out of a message ('twist.twist.linear.x'; 'yaw' of an odometry's orientation)."""
    if path == 'yaw':
        q = msg['pose']['pose']['orientation']
        return math.atan2(2 * (q['w'] * q['z'] + q['x'] * q['y']), 1 - 2 * (q['y'] ** 2 + q['z'] ** 2))
    v = msg
    for part in path.split('.'):
        v = v[part]
    return v


def numeric_paths(msg: dict, prefix: str = '') -> list[str]:
    """The numeric scalar fields of a message (headers and arrays left out), at most MAX_FIELDS."""
    out: list[str] = []
    for key, value in msg.items():
        if key == 'header':
            continue
        path = f'{prefix}{key}'
        if isinstance(value, dict):
            out += numeric_paths(value, path + '.')
        elif isinstance(value, (int, float)):   # bools too: 0/1
            out.append(path)
    return out[:MAX_FIELDS]


class _Tap:
    """Stands where a client session would in a topic's fan-out (JSON frames, throttled)."""

    closed = False

    def __init__(self, history: History, topic: str, type: str):
        self.id = next(_tap_ids)
        self.history, self.topic, self.type = history, topic, type
        self.fields: tuple[str, ...] | None = KNOWN_FIELDS.get(type)
        self.outbox = self
        self.last = 0.0

    def message(self, frame: bytes, binary: bool, key: object, queue_length: int) -> bool:
        try:
            self.history.take(self, orjson.loads(frame)['msg'])
        except Exception:   # never into the fan-out loop: the live clients come first
            log.exception('history cannot take a message of %s', self.topic)
        return True

    def forget(self, key: object) -> None:
        pass


class History(Hook):
    """The topics kept (their taps), the points waiting for the next batch, the latest value of
    each field (to ``events``: ``on_history_point``, the OPC UA face), and the store work: batches, roll-ups, cap.
    It reads through the topics' fan-outs (``taps``) what ``graph`` lists and ``names`` lets a client
    subscribe to; ``fleet``: the gateways on one PostgreSQL, of which only the timekeeper writes
    (None: this one alone). A history that only writes and reads (the bench, the store's tests) is
    given the store alone."""

    def __init__(self, globs: tuple[str, ...] | None, *, max_bytes: int, full_seconds: float,
                 store: Store | None = None, taps: Taps | None = None, graph: Graph | None = None,
                 names: Names | None = None, fleet: Timekeeper | None = None, events: Points | None = None):
        self.globs, self.store, self.fleet, self.events = globs, store, fleet, events
        self.fanouts, self.graph, self.names = taps, graph, names   # (self.taps: the topics kept)
        self.max_bytes, self.full_seconds = max_bytes, full_seconds
        self.taps: dict[str, tuple] = {}              # topic -> (fanout, _Tap)
        self.refused: set[str] = set()                # topics that cannot be kept (logged once)
        self.pending: list[tuple[str, str, int, float]] = []   # (topic, field, t_ms, v)
        self.latest: dict[tuple[str, str], tuple[float, float]] = {}
        self.ids: dict[tuple[str, str], int] = {}     # series ids, used on the store's thread only
        self.rows = 0                                 # written since start
        self.window: deque[tuple[float, int]] = deque(maxlen=64)   # (time, rows) after each batch
        self.tasks: list[asyncio.Task] = []

    # --- which topics -----------------------------------------------------------------------

    def wants(self, topic: str, type: str) -> bool:
        if self.globs is None:
            return type in DEFAULT_TYPES
        return any(fnmatchcase(topic, g) for g in self.globs)

    def match(self) -> None:
        backend = self.graph
        for topic in [t for t in self.taps if not backend.publishers(t)]:
            self.release(topic)   # its robot is gone: the history's subscription must not keep the name listed
        for topic, type in backend.topics():
            if topic in self.taps or topic in self.refused or not self.wants(topic, type):
                continue
            if may(self.names, None, 'subscribe', topic) is not None:
                continue
            if not backend.publishers(topic):
                continue   # only looked for (a page's subscription): nothing of the robot's to keep
            fan = None
            try:
                fan = self.fanouts.fanout(topic, type)
                tap = _Tap(self, topic, type)
                fan.add(tap, None, (THROTTLE_MS, 1, 'none', None))
            except Exception as e:   # an unknown type, a topic of two types, ...
                if fan is not None and not fan.subscribers:
                    self.fanouts.drop_fanout(fan)   # made here for nothing: no backend subscription left behind
                self.refused.add(topic)
                log.warning('history cannot keep %s (%s): %s', topic, type, e)
                continue
            self.taps[topic] = (fan, tap)
            log.info('history keeps %s (%s)', topic, type)

    def release(self, topic: str) -> None:
        fan, tap = self.taps.pop(topic)
        fan.remove(tap, None)
        log.info('history no longer keeps %s: nothing publishes it', topic)

    def kept_fields(self, topic: str) -> tuple[str, ...] | None:
        """The fields of a live kept topic (None: not kept, or no message seen yet)."""
        entry = self.taps.get(topic)
        return entry[1].fields if entry is not None else None

    # --- taking points (on the loop) --------------------------------------------------------

    def take(self, tap: _Tap, msg: dict) -> None:
        now = time.time()
        if now - tap.last < MIN_GAP:
            return
        tap.last = now
        if tap.fields is None:
            tap.fields = tuple(numeric_paths(msg))
        t_ms = int(now * 1000)
        for path in tap.fields:
            try:
                v = float(field_value(msg, path))
            except (KeyError, TypeError, ValueError, ZeroDivisionError):
                continue
            if not math.isfinite(v):
                continue
            self.pending.append((tap.topic, path, t_ms, v))
            self.latest[(tap.topic, path)] = (now, v)
            if self.events is not None:
                self.events.history_point(tap.topic, path, now, v)   # on_history_point (the OPC UA twin)

    def writes(self) -> bool:
        """Whether this gateway writes the history: alone, yes; in a fleet of gateways on one
        PostgreSQL (store.fleet) only its timekeeper does, so each series is written once."""
        return self.fleet is None or self.fleet.timekeeper

    def flush(self) -> None:
        if not self.writes():
            self.pending = []   # the points stay live here (latest, on_history_point); the timekeeper keeps them
            return
        if self.pending:
            batch, self.pending = self.pending, []
            self.store.submit(lambda conn: self._write(conn, batch))

    # --- on the store's thread --------------------------------------------------------------

    def series_id(self, conn: sa.Connection, topic: str, field: str, create: bool = True) -> int | None:
        key = (topic, field)
        sid = self.ids.get(key)
        if sid is None:
            sid = conn.execute(sa.select(SERIES.c.id).where(SERIES.c.topic == topic, SERIES.c.field == field)).scalar()
            if sid is None and create:
                sid = conn.execute(SERIES.insert().values(topic=topic, field=field)).inserted_primary_key[0]
            if sid is not None:
                self.ids[key] = sid
        return sid

    def _write(self, conn: sa.Connection, batch: list) -> None:
        rows = [{'series': self.series_id(conn, topic, field), 't': t, 'v': v} for topic, field, t, v in batch]
        conn.execute(POINTS.insert(), rows)
        self.rows += len(rows)
        self.window.append((time.monotonic(), self.rows))

    def compact(self, conn: sa.Connection, now: float | None = None) -> None:
        """Points older than the full-rate span become per-minute rows; then the size cap."""
        now = time.time() if now is None else now
        cut = int((now - self.full_seconds) * 1000)
        cut -= cut % MINUTE
        minute = POINTS.c.t.op('/')(sa.literal_column(str(MINUTE)))
        rollup = (sa.select(POINTS.c.series, (minute * sa.literal_column(str(MINUTE))).label('t'),
                            sa.func.count().label('n'), sa.func.min(POINTS.c.v), sa.func.avg(POINTS.c.v),
                            sa.func.max(POINTS.c.v))
                  .where(POINTS.c.t < cut).group_by(POINTS.c.series, minute))
        conn.execute(MINUTES.insert().from_select(['series', 't', 'n', 'vmin', 'vmean', 'vmax'], rollup))
        conn.execute(POINTS.delete().where(POINTS.c.t < cut))
        self.cap(conn)

    def used_bytes(self, conn: sa.Connection) -> int:
        """Bytes the database holds in use (SQLite: its pages less the free ones, which new rows reuse)."""
        dialect = conn.dialect.name
        if dialect == 'sqlite':
            pages = conn.exec_driver_sql('PRAGMA page_count').scalar()
            free = conn.exec_driver_sql('PRAGMA freelist_count').scalar()
            size = conn.exec_driver_sql('PRAGMA page_size').scalar()
            return (pages - free) * size
        if dialect == 'postgresql':
            return int(sum(conn.execute(sa.text(f"SELECT pg_total_relation_size('{t.name}')")).scalar()
                           for t in (SERIES, POINTS, MINUTES)))
        return 0

    def cap(self, conn: sa.Connection) -> None:
        if self.used_bytes(conn) <= self.max_bytes:
            return
        lows = [conn.execute(sa.select(sa.func.min(t.c.t))).scalar() for t in (MINUTES, POINTS)]
        lows = [x for x in lows if x is not None]
        if not lows:
            return
        lo = min(lows)
        hi = int(time.time() * 1000)
        cut = lo + max(MINUTE, (hi - lo) // 10)
        gone = conn.execute(MINUTES.delete().where(MINUTES.c.t < cut)).rowcount
        gone += conn.execute(POINTS.delete().where(POINTS.c.t < cut)).rowcount
        log.warning('history over its cap of %d MiB: the oldest %d rows (before %s) deleted',
                    self.max_bytes // 2**20, gone, time.strftime('%Y-%m-%d %H:%M', time.localtime(cut / 1000)))

    # --- figures ----------------------------------------------------------------------------

    def rate(self) -> float:
        """Rows written per second, over the last minute or so of batches."""
        w = list(self.window)
        if len(w) < 2:
            return 0.0
        now = time.monotonic()
        recent = [x for x in w if now - x[0] <= 60] or w[-2:]
        first, last = (recent[0] if len(recent) > 1 else w[-2]), recent[-1]
        return (last[1] - first[1]) / (last[0] - first[0]) if last[0] > first[0] else 0.0

    def stats(self, size: int, used: int) -> dict:
        return {'db': self.store.url, 'bytes': size, 'used_bytes': used, 'max_bytes': self.max_bytes,
                'rows_written': self.rows, 'rows_per_second': round(self.rate(), 3),
                'full_rate_hours': self.full_seconds / 3600, 'topics': sorted(self.taps),
                'kept': list(self.globs) if self.globs is not None else [f'type {t}' for t in DEFAULT_TYPES]}

    # --- lifecycle --------------------------------------------------------------------------

    def start(self) -> None:
        self.match()
        for every, job in ((POLL, self.match), (FLUSH, self.flush),
                           (COMPACT_EVERY, lambda: self.writes() and self.store.submit(self.compact)),
                           (REPORT_EVERY, self.report)):
            self.tasks.append(asyncio.ensure_future(_every(every, job)))

    def report(self) -> None:
        size = self.store.size()
        log.info('history: %.1f rows/s, %d rows this run, database %.1f MiB (%s)',
                 self.rate(), self.rows, size / 2**20, self.store.url)

    def on_shutdown(self) -> None:
        for task in self.tasks:
            task.cancel()
        for fan, tap in self.taps.values():
            fan.remove(tap, None)
        self.taps.clear()
        self.flush()   # the store closes after the hooks, once this batch is written


async def _every(seconds: float, job) -> None:
    while True:
        await asyncio.sleep(seconds)
        try:
            job()
        except Exception:
            log.exception('history: %s failed', getattr(job, '__name__', 'a periodic job'))


def history_globs(value: str | None) -> tuple[str, ...] | None | bool:
    """--history: None (the default types), False (none: off) or the globs."""
    if value is not None and value.strip().lower() in ('none', 'off', '[]', ''):
        return False
    return parse_globs(value)


def start_history(s: TwinSettings, events: Points, *, store: Store, taps: Taps, graph: Graph, names: Names,
                  fleet: Timekeeper | None) -> History | None:
    """The gateway's history as its settings ask (None with --history none); it starts keeping now."""
    globs = history_globs(s.history)
    if globs is False:
        return None
    history = History(globs, max_bytes=int(s.history_max_mb * 2**20), full_seconds=s.history_full_hours * 3600,
                      store=store, taps=taps, graph=graph, names=names, fleet=fleet, events=events)
    history.start()   # a part of the gateway's hooks (server.start)
    return history
