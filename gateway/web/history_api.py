"""Reading the gateway's history over HTTP.

GET /api/history                          -> {"series": [{"topic", "fields": [...]}, ...]} (what the caller may read)
GET /api/history?topic=T&field=F&from=EPOCH&to=EPOCH[&step=S][&format=csv]
                                          -> {"topic", "field", "t": [...], "v": [...]}
                                             (+ "min", "max" per point when downsampled or per-minute)
GET /api/history/stats                    -> database size, rows written per second, topics kept

``from`` defaults to ten minutes before ``to``, ``to`` to now. Without ``step`` the points come
as kept: 1 Hz for the recent span, one per minute (its mean, with min and max) before that. With
``step`` (seconds) they are grouped into buckets of that length (t: the bucket's middle, v: the
mean, min and max). A span with no data gives empty arrays. A topic outside the history, or a
field it does not keep, gets 404 saying what it keeps; a bad number 400. Reading a topic's history
is subscribing to its past: the same name globs, roles and tokens apply as to a subscribe (403).
"""

from __future__ import annotations

import time

import orjson
import sqlalchemy as sa
import tornado.web

from ..rules.access import acts_as_admin, may
from .api import JsonHandler, caller, query_number
from ..twin.history import MINUTE, MINUTES, POINTS, SERIES, History

DEFAULT_SPAN = 600.0
LATEST = 1e11        # s since 1970 (the year 5138): a larger from, to or step is no time the store can hold
RAW = 'SELECT CAST(t AS DOUBLE PRECISION) / 1000, v FROM history_points WHERE series = {s} AND t >= {lo} AND t <= {hi} ORDER BY t'


def raw_points(conn: sa.Connection, sid: int, lo: int, hi: int) -> tuple[list, list]:
    """The full-rate points of a span as (t in s, v) lists, straight from the driver's cursor: a
    day is 86,400 rows, and SQLAlchemy's rows and result types cost more than the rest of the read."""
    style = conn.dialect.paramstyle
    if style == 'qmark':
        sql, params = RAW.format(s='?', lo='?', hi='?'), (sid, lo, hi)
    elif style in ('format', 'pyformat'):
        sql, params = RAW.format(s='%s', lo='%s', hi='%s'), (sid, lo, hi)
    else:
        return _portable(conn, sid, lo, hi)
    rows = conn.exec_driver_sql(sql, params).cursor.fetchall()
    if not rows:
        return [], []
    ts, vs = zip(*rows)
    return list(ts), list(vs)


RAW_JSON = {   # the arrays written by the database itself, in C: a day of one field in a third of the time
    'sqlite': 'SELECT json_group_array(t / 1000.0), json_group_array(v) FROM (SELECT t, v FROM history_points '
              'WHERE series = :s AND t >= :lo AND t <= :hi ORDER BY t)',
    'postgresql': "SELECT COALESCE(json_agg(t / 1000.0 ORDER BY t), '[]')::text, "
                  "COALESCE(json_agg(v ORDER BY t), '[]')::text FROM history_points "
                  'WHERE series = :s AND t >= :lo AND t <= :hi',
}


def raw_json(conn: sa.Connection, sid: int, lo: int, hi: int) -> tuple[str, str] | None:
    """The full-rate points of a span as two JSON arrays (t in s, v), or None for a database
    without JSON aggregates."""
    sql = RAW_JSON.get(conn.dialect.name)
    if sql is None:
        return None
    t, v = conn.execute(sa.text(sql), {'s': sid, 'lo': lo, 'hi': hi}).one()
    return t, v


def _portable(conn: sa.Connection, sid: int, lo: int, hi: int) -> tuple[list, list]:
    p = POINTS.c
    rows = conn.execute(sa.select(p.t, p.v).where(p.series == sid, p.t >= lo, p.t <= hi).order_by(p.t)).all()
    return [r[0] / 1000 for r in rows], [r[1] for r in rows]
MAX_BUCKETS = 200_000


def query(conn: sa.Connection, sid: int, lo: int, hi: int, step: int | None, as_json: bool = False) -> dict:
    """Points of one series between lo and hi (ms, inclusive); step in ms, or None for as kept.
    as_json: the arrays may come as orjson Fragments (JSON the database wrote) instead of lists."""
    p, m = POINTS.c, MINUTES.c
    if step is None:
        mins = conn.execute(sa.select(m.t, m.vmean, m.vmin, m.vmax)
                            .where(m.series == sid, m.t >= lo - MINUTE // 2, m.t <= hi - MINUTE // 2)
                            .order_by(m.t)).all()
        fast = raw_json(conn, sid, lo, hi) if as_json and not mins else None
        if fast is not None:
            return {'t': orjson.Fragment(fast[0]), 'v': orjson.Fragment(fast[1])}
        ts, vs = raw_points(conn, sid, lo, hi)
        out = {'t': [(r[0] + MINUTE // 2) / 1000 for r in mins] + ts, 'v': [r[1] for r in mins] + vs}
        if mins:
            out['min'] = [r[2] for r in mins] + vs
            out['max'] = [r[3] for r in mins] + vs
        return out
    size = sa.literal_column(str(step))
    pb, mb = p.t.op('/')(size), m.t.op('/')(size)
    buckets: dict[int, list] = {}   # bucket -> [n, sum, min, max]
    for table, b, n, total, lo_v, hi_v in (
            (POINTS, pb, sa.func.count(), sa.func.sum(p.v), sa.func.min(p.v), sa.func.max(p.v)),
            (MINUTES, mb, sa.func.sum(m.n), sa.func.sum(m.vmean * m.n), sa.func.min(m.vmin), sa.func.max(m.vmax))):
        rows = conn.execute(sa.select(b, n, total, lo_v, hi_v)
                            .where(table.c.series == sid, table.c.t >= lo, table.c.t <= hi).group_by(b))
        for key, count, s, vmin, vmax in rows:
            have = buckets.get(key)
            if have is None:
                buckets[key] = [int(count), float(s), vmin, vmax]
            else:
                have[0] += int(count)
                have[1] += float(s)
                have[2], have[3] = min(have[2], vmin), max(have[3], vmax)
    keys = sorted(buckets)
    return {'t': [(k * step + step / 2) / 1000 for k in keys],
            'v': [buckets[k][1] / buckets[k][0] for k in keys],
            'min': [buckets[k][2] for k in keys], 'max': [buckets[k][3] for k in keys]}


def listing(conn: sa.Connection) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for topic, field in conn.execute(sa.select(SERIES.c.topic, SERIES.c.field).order_by(SERIES.c.id)):
        out.setdefault(topic, []).append(field)
    return out


class _Handler(JsonHandler):
    def initialize(self, history: History) -> None:
        self.history = history

    def may_read(self, identity, topic: str) -> bool:
        """A read of a topic's past is a subscribe to it: the globs and the role decide."""
        self.refusal = may(self.history.gateway.policy, identity, 'subscribe', topic)
        return self.refusal is None


class HistoryHandler(_Handler):
    async def get(self) -> None:
        h = self.history
        identity = caller(self, h.gateway)
        topic = self.get_query_argument('topic', None)
        known = await h.store.run(listing)
        for live in h.taps:
            fields = h.kept_fields(live)
            known.setdefault(live, [])
            known[live] += [f for f in fields or () if f not in known[live]]
        if topic is None:
            self.finish({'series': [{'topic': t, 'fields': f} for t, f in sorted(known.items())
                                    if self.may_read(identity, t)]})
            return
        field = self.get_query_argument('field', None)
        if not field:
            raise tornado.web.HTTPError(400, 'give a field, e.g. &field=percentage')
        if not self.may_read(identity, topic):
            raise tornado.web.HTTPError(403, self.refusal)
        if topic not in known:
            kept = ', '.join(sorted(known)[:20]) or 'nothing yet'
            raise tornado.web.HTTPError(404, f'{topic[:200]} is not in the history (--history); it keeps {kept}')
        if field not in known[topic]:
            raise tornado.web.HTTPError(404, f'the history of {topic} has no field {field[:100]!r}; '
                                             f'it keeps {", ".join(known[topic]) or "no field yet"}')
        to = self.number('to', time.time())
        start = self.number('from', to - DEFAULT_SPAN)
        if start > to:
            raise tornado.web.HTTPError(400, f'"from" ({start:g}) is after "to" ({to:g})')
        step = self.get_query_argument('step', None)
        step_ms = None
        if step is not None:
            s = self.number('step', 0)
            if not s > 0:
                raise tornado.web.HTTPError(400, '"step" is a number of seconds above 0')
            if (to - start) / s > MAX_BUCKETS:
                raise tornado.web.HTTPError(400, f'"step" of {s:g} s gives more than {MAX_BUCKETS} points; take a longer one')
            step_ms = max(1, int(s * 1000))
        fmt = self.get_query_argument('format', 'json')
        if fmt not in ('json', 'csv'):
            raise tornado.web.HTTPError(400, '"format" is json or csv')
        lo, hi = int(start * 1000), int(to * 1000)

        def read(conn):
            sid = h.series_id(conn, topic, field, create=False)
            return {'t': [], 'v': []} if sid is None else query(conn, sid, lo, hi, step_ms, as_json=fmt == 'json')

        data = await h.store.run(read)
        if fmt == 'csv':
            self.set_header('Content-Type', 'text/csv; charset=utf-8')
            self.set_header('Content-Disposition', f'attachment; filename="history.csv"')
            cols = ['t', 'v'] + [c for c in ('min', 'max') if c in data]
            self.write(','.join(cols) + '\n')
            self.finish(''.join(','.join(repr(data[c][i]) for c in cols) + '\n' for i in range(len(data['t']))))
            return
        self.finish(orjson.dumps({'topic': topic, 'field': field, 'from': start, 'to': to,
                                  **({'step': step_ms / 1000} if step_ms else {}), **data}))

    def number(self, name: str, default: float) -> float:
        return query_number(self, name, default, 'a number of seconds (since 1970 for from and to)',
                            low=0, high=LATEST)


class HistoryStatsHandler(_Handler):
    async def get(self) -> None:
        h = self.history
        identity = caller(self, h.gateway)
        used = await h.store.run(h.used_bytes)
        size = await h.store.run(lambda conn: h.store.size()) if not h.store.sqlite else h.store.size()
        stats = h.stats(size, used)
        if not acts_as_admin(identity):   # where the database is (a path, a host) is the admins'
            stats['db'] = stats['db'].split(':', 1)[0]
        self.finish(stats)


def history_routes(history: History | None) -> list:
    if history is None:
        return [(r'/api/history(?:/stats)?', _Off)]
    kw = {'history': history}
    return [(r'/api/history/?', HistoryHandler, kw), (r'/api/history/stats', HistoryStatsHandler, kw)]


class _Off(JsonHandler):
    def get(self) -> None:
        raise tornado.web.HTTPError(404, 'this gateway keeps no history (started with --history none)')
