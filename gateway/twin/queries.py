"""Reading the history back (``twin.history`` keeps it; ``web.history`` is its HTTP face): one
series' points of a span as kept (1 Hz recently, per minute before) or grouped into buckets of a
step, and the list of series. Each function takes a connection of the store's (``Store.run``);
``series``, ``points`` and ``figures`` are what the HTTP face awaits, the store's work done on its
thread (web/ holds no SQL).
"""

from __future__ import annotations

import orjson
import sqlalchemy as sa

from .history import MINUTE, MINUTES, POINTS, SERIES, History

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


async def series(history: History) -> dict[str, list[str]]:
    """Every series by topic: those in the store, and those kept live here but not written yet."""
    known = await history.store.run(listing)
    for live in history.taps:
        known.setdefault(live, [])
        known[live] += [f for f in history.kept_fields(live) or () if f not in known[live]]
    return known


async def points(history: History, topic: str, field: str, lo: int, hi: int, step: int | None,
                 as_json: bool = False) -> dict:
    """One series' points from ``lo`` to ``hi`` (ms), as ``query`` gives them; none for a series
    never written."""
    def read(conn: sa.Connection) -> dict:
        sid = history.series_id(conn, topic, field, create=False)
        return {'t': [], 'v': []} if sid is None else query(conn, sid, lo, hi, step, as_json=as_json)
    return await history.store.run(read)


async def figures(history: History) -> dict:
    """The history's figures (``History.stats``): the database's size and the bytes in use."""
    store = history.store
    used = await store.run(history.used_bytes)
    size = await store.run(lambda conn: store.size()) if not store.sqlite else store.size()
    return history.stats(size, used)
