"""The gateway's history: what keeping it costs, and how fast a day of it reads.

    .venv/bin/python -m tests.bench history                 # 60 s of writing, a day's read
    make bench ARGS="history --seconds 30 --out history.json"

Writing: 30 stations x 5 fields (a BatteryState each: percentage, voltage, current, charge,
temperature) at 1 Hz for ``--seconds`` seconds, through the history's own path: each message
encoded as the fan-out encodes it for a JSON subscriber, handed to the history's tap (which parses
it back, takes the fields, queues the points), batched to the store's thread every 2 s, into
SQLite with WAL in a temporary folder; one roll-up (compaction) in the middle. The cost is the
CPU time of this process (all its threads, the store's included) over the wall time, in % of one
core, with what the rest of the machine used meanwhile beside it.

Reading: a store holding one day of 1 Hz points for 10 series (864,000 rows), then a gateway
(``--robot none``) started on it, asked ``GET /api/history`` for one field over the whole day
(86,400 points as JSON), raw and with ``step=60``; and the same query in-process without HTTP.
Median and p95 of 10 reads each.

The bar (issue 30): writing < 2 % of a core; a day's read of one field < 100 ms, judged on the
gateway's CPU time per read (its wall time is printed beside it, with how busy the machine was:
on a machine others load, the wall time measures them).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
import urllib.request

import orjson

from gateway.bridge import encode
from gateway.rules.hooks import Hooks
from gateway.store import Store
from gateway.twin.history import FLUSH, History, _Tap
from gateway.twin.queries import query

from .report import save
from .servers import machine_busy_s, start_rosgate

STATIONS, TYPE = 30, 'sensor_msgs/msg/BatteryState'
DAY = 86_400
BAR_WRITE_PCT, BAR_READ_MS = 2.0, 100.0


class _Gateway:
    """What the history asks of a gateway when it only writes: its store, and its rules (no fleet
    of gateways here: this one writes)."""

    def __init__(self, store: Store):
        self.store = store
        self.ruleset = None
        self.hooks = Hooks()   # nobody follows its points here


def battery(i: int, t: float) -> dict:
    pct = 1.0 - (t % 3600) / 7200 - i / 1000
    return {'header': {'stamp': {'sec': int(t), 'nanosec': 0}, 'frame_id': f's{i:02d}/base_link'},
            'voltage': 10.5 + 2.1 * pct, 'temperature': 25.0, 'current': -0.25, 'charge': 2 * pct,
            'capacity': 2.0, 'design_capacity': 2.0, 'percentage': pct, 'power_supply_status': 2,
            'power_supply_health': 1, 'power_supply_technology': 3, 'present': True, 'cell_voltage': [],
            'cell_temperature': [], 'location': 'base', 'serial_number': ''}


async def write_load(seconds: float, folder: str) -> dict:
    store = Store(f'sqlite:///{folder}/write.db')
    history = History(_Gateway(store), None, max_bytes=2**30, full_seconds=DAY)
    taps = [_Tap(history, f'/s{i:02d}/battery_state', TYPE) for i in range(1, STATIONS + 1)]
    flushes = asyncio.ensure_future(_every(FLUSH, history.flush))
    cpu0, wall0, busy0 = time.process_time(), time.monotonic(), machine_busy_s()
    compacted = False
    tick = wall0
    while time.monotonic() - wall0 < seconds:
        now = time.time()
        for i, tap in enumerate(taps, start=1):
            (frame, binary), = encode.frames({'op': 'publish', 'topic': tap.topic, 'msg': battery(i, now)})
            tap.message(frame, binary, None, 1)
        if not compacted and time.monotonic() - wall0 > seconds / 2:
            store.submit(history.compact)
            compacted = True
        tick += 1.0
        await asyncio.sleep(max(0.0, tick - time.monotonic()))
    flushes.cancel()
    history.flush()
    await store.run(lambda c: None)   # the last batch written
    wall, cpu, busy = time.monotonic() - wall0, time.process_time() - cpu0, machine_busy_s() - busy0
    size = store.size()
    store.close()
    return {'stations': STATIONS, 'fields': 5, 'seconds': round(wall, 1), 'rows': history.rows,
            'rows_per_s': round(history.rows / wall, 1), 'cpu_pct_of_core': round(100 * cpu / wall, 3),
            'other_cpu_pct': round(100 * (busy - cpu) / wall, 1), 'db_bytes': size}


async def _every(seconds: float, job) -> None:
    while True:
        await asyncio.sleep(seconds)
        job()


def fill_day(data_home: str, series: int = 10) -> tuple[float, float]:
    """A day of 1 Hz points for some series in the store a gateway with this XDG_DATA_HOME opens."""
    store = Store(f"sqlite:///{data_home}/rosgate/rosgate.db")
    history = History(_Gateway(store), None, max_bytes=2**31, full_seconds=2 * DAY)
    end = time.time()
    start = end - DAY
    for s in range(series):
        rows = [(f'/s{s + 1:02d}/battery_state', 'percentage', int((start + k) * 1000), 1 - k / DAY) for k in range(DAY)]
        for i in range(0, DAY, 20_000):
            store.run_now(lambda c, part=rows[i:i + 20_000]: history._write(c, part))
    store.close()
    return start, end


def timed(fn, n: int = 10) -> dict:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        out.append((time.perf_counter() - t0) * 1000)
    out.sort()
    return {'min_ms': round(out[0], 1), 'p50_ms': round(statistics.median(out), 1),
            'p95_ms': round(out[int(0.95 * (len(out) - 1))], 1)}


def cpu_s(pid: int) -> float:
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def read_load(folder: str, series: int = 10) -> dict:
    home = os.path.join(folder, 'data')
    start, end = fill_day(home, series)
    busy0, wall0 = machine_busy_s(), time.monotonic()
    store = Store(f"sqlite:///{home}/rosgate/rosgate.db")
    h = History(_Gateway(store), None, max_bytes=2**31, full_seconds=2 * DAY)
    sid = store.run_now(lambda c: h.series_id(c, '/s01/battery_state', 'percentage', create=False))
    lo, hi = int(start * 1000), int(end * 1000)
    points = len(store.run_now(lambda c: query(c, sid, lo, hi, None))['t'])
    inproc = timed(lambda: orjson.dumps(store.run_now(lambda c: query(c, sid, lo, hi, None, as_json=True))))
    size = store.size()
    store.close()
    os.environ['XDG_DATA_HOME'] = home
    gw = start_rosgate(['--backend', 'sim', '--robot', 'none', '--history', "['/nothing']",
                        '--programs-dir', os.path.join(folder, 'programs')])
    http_url = gw.url.replace('ws://', 'http://').rstrip('/') + '/'
    try:
        base = f"{http_url}api/history?topic=/s01/battery_state&field=percentage&from={start}&to={end}"

        def get(url):
            with urllib.request.urlopen(url, timeout=30) as res:
                body = orjson.loads(res.read())
            assert body['t'], body
            return body
        http_points = len(get(base)['t'])
        cpu0 = cpu_s(gw.pid)
        raw = timed(lambda: get(base))
        raw['server_cpu_ms'] = round((cpu_s(gw.pid) - cpu0) * 100, 1)   # per read: 10 reads
        cpu0 = cpu_s(gw.pid)
        stepped = timed(lambda: get(base + '&step=60'))
        stepped['server_cpu_ms'] = round((cpu_s(gw.pid) - cpu0) * 100, 1)
    finally:
        gw.stop()
    load = round(100 * (machine_busy_s() - busy0) / (time.monotonic() - wall0), 1)
    return {'rows_in_store': series * DAY, 'db_bytes': size, 'machine_cpu_pct': load, 'points': points, 'http_points': http_points,
            'inprocess': inproc, 'http_raw': raw, 'http_step60': stepped}


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog='python -m tests.bench history')
    p.add_argument('--seconds', type=float, default=60.0, help='of writing [%(default)s]')
    p.add_argument('--series', type=int, default=10, help='series of a day each in the store read [%(default)s]')
    p.add_argument('--out', help='write the figures as JSON here')
    args = p.parse_args(argv)
    folder = tempfile.mkdtemp(prefix='rosgate-bench-history-')
    try:
        write = asyncio.run(write_load(args.seconds, folder))
        read = read_load(folder, args.series)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    ok_write = write['cpu_pct_of_core'] < BAR_WRITE_PCT
    # judged on the gateway's CPU per read: the wall time on a machine others load says more about them
    ok_read = read['http_raw']['server_cpu_ms'] < BAR_READ_MS
    print(f"history write: {write['stations']} stations x {write['fields']} fields at 1 Hz for {write['seconds']} s: "
          f"{write['rows_per_s']} rows/s, {write['cpu_pct_of_core']} % of a core "
          f"(other load {write['other_cpu_pct']} %), database {write['db_bytes'] / 2**20:.1f} MiB "
          f"[bar < {BAR_WRITE_PCT} %: {'ok' if ok_write else 'MISSED'}]")
    print(f"history read: one field over a day ({read['points']} points of {read['rows_in_store']} rows, "
          f"{read['db_bytes'] / 2**20:.0f} MiB): HTTP raw min {read['http_raw']['min_ms']} ms p50 {read['http_raw']['p50_ms']} ms "
          f"p95 {read['http_raw']['p95_ms']} ms, server CPU {read['http_raw']['server_cpu_ms']} ms a read; step=60 p50 {read['http_step60']['p50_ms']} ms; "
          f"in-process p50 {read['inprocess']['p50_ms']} ms; machine busy {read['machine_cpu_pct']} % of 200 "
          f"[bar: server CPU < {BAR_READ_MS:g} ms a read: {'ok' if ok_read else 'MISSED'}]")
    save(args.out, {'write': write, 'read': read})
    return 0 if ok_write and ok_read else 1


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
