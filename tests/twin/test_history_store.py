"""The history's tables in the one store: the roll-up of old points into per-minute min/mean/max,
the reads with and without step, the size cap; on SQLite and on Debian's PostgreSQL, which the
test starts itself on loopback."""

from __future__ import annotations

import os
import time

import orjson
import pytest
import sqlalchemy as sa

from gateway.store import Store
from gateway.twin.history import MINUTES, POINTS, History
from gateway.twin.queries import listing, query
from tests.support.postgres import postgres_server

HOUR = 3600
postgres = pytest.fixture(scope='module')(postgres_server)


@pytest.fixture(params=['sqlite', 'postgresql'])
def store(request, tmp_path):
    url = f'sqlite:///{tmp_path}/rosgate.db' if request.param == 'sqlite' else request.getfixturevalue('postgres')
    s = Store(url)
    yield s
    s.run_now(lambda c: [c.execute(t.delete()) for t in (POINTS, MINUTES)])
    s.close()


def three_hours(store: Store, h: History, end: float) -> list[tuple[int, float]]:
    """Points at 1 Hz over the three hours before ``end``; v is the second's index."""
    start = int(end) - 3 * HOUR
    points = [((start + i) * 1000, float(i)) for i in range(3 * HOUR)]
    store.run_now(lambda c: h._write(c, [('/r/battery_state', 'percentage', t, v) for t, v in points]))
    return points


def test_old_points_become_minutes_and_reads_span_both(store):
    h = History(None, max_bytes=2**30, full_seconds=HOUR)
    end = (time.time() // 60) * 60
    points = three_hours(store, h, end)
    store.run_now(lambda c: h.compact(c, now=end))

    sid = store.run_now(lambda c: h.series_id(c, '/r/battery_state', 'percentage', create=False))
    n_points = store.run_now(lambda c: c.execute(sa.select(sa.func.count()).select_from(POINTS)).scalar())
    minutes = store.run_now(lambda c: c.execute(sa.select(MINUTES).order_by(MINUTES.c.t)).all())
    assert n_points == HOUR                              # the last hour at full rate
    assert len(minutes) == 120                           # the two hours before, one row a minute
    first = minutes[0]
    assert (first.n, first.vmin, first.vmax) == (60, 0.0, 59.0) and first.vmean == pytest.approx(29.5)

    lo, hi = points[0][0], points[-1][0]
    raw = store.run_now(lambda c: query(c, sid, lo, hi, None))
    assert len(raw['t']) == 120 + HOUR and raw['t'] == sorted(raw['t'])
    assert raw['min'][0] == 0.0 and raw['max'][0] == 59.0 and raw['v'][0] == pytest.approx(29.5)
    assert raw['v'][-1] == 3 * HOUR - 1 and raw['min'][-1] == raw['max'][-1] == raw['v'][-1]

    ten = store.run_now(lambda c: query(c, sid, lo, hi, 600_000))   # 10 min buckets over both tables
    assert len(ten['t']) in (18, 19)
    assert min(ten['min']) == 0.0 and max(ten['max']) == 3 * HOUR - 1
    for a, v, b in zip(ten['min'], ten['v'], ten['max']):
        assert a <= v <= b
    whole = store.run_now(lambda c: query(c, sid, lo, hi, 10**12))   # one bucket: minutes weigh by their count
    assert len(whole['v']) == 1 and whole['v'][0] == pytest.approx((3 * HOUR - 1) / 2)

    empty = store.run_now(lambda c: query(c, sid, 1000, 2000, None))
    assert empty == {'t': [], 'v': []}
    # the JSON the database writes for the full-rate span equals the lists
    recent = points[-HOUR][0]
    as_lists = store.run_now(lambda c: query(c, sid, recent, hi, None))
    as_json = store.run_now(lambda c: query(c, sid, recent, hi, None, as_json=True))
    assert isinstance(as_json['t'], orjson.Fragment) and 'min' not in as_json
    decoded = orjson.loads(orjson.dumps(as_json))
    assert decoded['v'] == as_lists['v'] and len(decoded['t']) == HOUR
    assert decoded['t'] == pytest.approx(as_lists['t'], abs=1e-6)
    none = orjson.loads(orjson.dumps(store.run_now(lambda c: query(c, sid, 1000, 2000, None, as_json=True))))
    assert none == {'t': [], 'v': []}
    assert store.run_now(listing) == {'/r/battery_state': ['percentage']}


def test_over_the_cap_the_oldest_tenth_goes(store):
    h = History(None, max_bytes=2**30, full_seconds=24 * HOUR)
    end = time.time()
    points = three_hours(store, h, end)
    used = store.run_now(h.used_bytes)
    assert used > 0
    h.max_bytes = used // 2
    store.run_now(h.cap)
    oldest = store.run_now(lambda c: c.execute(sa.select(sa.func.min(POINTS.c.t))).scalar())
    assert oldest >= points[0][0] + 0.1 * (end * 1000 - points[0][0]) - 1   # the oldest tenth of the span
    assert oldest < points[0][0] + 0.2 * 3 * HOUR * 1000                    # and not much more


def test_a_gateway_keeps_its_history_in_postgresql(start_gateway, postgres):
    from tests.support.http import api
    from tests.support.wait import wait_for

    gw = start_gateway('--robot', 'rover', '--db', postgres)
    body = wait_for(lambda: (lambda b: b if len(b.get('t', [])) >= 3 else None)(
        api(gw, 'GET', '/api/history?topic=/battery_state&field=percentage&from=0')[1]), 20, 0.2)
    assert all(0 < v <= 1 for v in body['v'])
    status, stats = api(gw, 'GET', '/api/history/stats')
    assert status == 200 and stats['db'].startswith('postgresql+psycopg://rosgate@127.0.0.1')
    assert stats['bytes'] > 0 and stats['used_bytes'] > 0
    gw.stop()
    engine = sa.create_engine(postgres)
    with engine.connect() as c:
        kept = c.execute(sa.text("SELECT count(*) FROM history_points p JOIN history_series s ON s.id = p.series "
                                 "WHERE s.topic = '/battery_state'")).scalar()
    engine.dispose()
    assert kept >= 3
