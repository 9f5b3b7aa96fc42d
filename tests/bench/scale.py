"""The class load over a fleet of 1, 2 and 4 gateways behind nginx (``python -m tests.bench scale``).

    .venv/bin/python -m tests.bench scale --minutes 1             # 30 pages on 1, 2 and 4 gateways
    .venv/bin/python -m tests.bench scale --gateways 1 2 --out scale.json

For each count N: N sim gateways of one fleet (``--robot turtlesim --fleet S --exclusive-control
--auth ... --db postgresql://...``) on one PostgreSQL of the bench's own (Debian's postgresql,
tests.support.postgres), and Debian's nginx in front of them (tests.support.nginx: the block of
docs/remote-lab.md without TLS, its ``proxy_pass`` to an upstream of the N gateways, round robin).
The lesson's S pages (tests/bench/lesson.py: each claims a station, follows its turtle's pose
and world markers, drives at 10 Hz and calls /rosapi/topics once a second), each signed in with
a token of its own, connect through nginx one after the other, so nginx deals them out to the
gateways in turn. Sim gateways do not share a robot graph: each simulates all S stations' turtles
in its own process, and a page drives the turtle of the gateway it reached; the claims (one
station per person, whichever gateway) and the driver leases are the fleet's, in PostgreSQL.

Figures per N, over the window after the warm-up: the messages the pages exchanged a second
(commands in, poses and markers out, rosapi calls); the gateways' CPU (their sum, 100 = one core)
and the throughput per core (messages a second per core used); the same with each gateway's idle
CPU taken off (measured before the pages come: its simulation of S turtles and the fleet's
beats, which a gateway on a real ROS graph would not have), and with nginx's and PostgreSQL's
CPU counted as well as the gateways'; nginx's and PostgreSQL's CPU;
rosapi p50/p95; PostgreSQL's committed transactions (``pg_stat_database.xact_commit``) a second
and per drive command. The machine's other load (``other``) is given too: on a shared machine
it makes the rows of one run comparable only with care.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import secrets
import sys
import tempfile
import time
from pathlib import Path

import sqlalchemy as sa
from websockets.exceptions import ConnectionClosed

from tests.support.nginx import guide_block, nginx
from tests.support.postgres import free_port, postgres_server
from tests.support.process import descendants

from .client import close_quietly, open_ws, percentile, send_op
from .lesson import Lesson, Minute, fmt, next_station
from .servers import ProcMeter, machine_busy_s, start_rosgate

IDLE = 5.0          # s of the gateways' idle CPU, before the pages come
WARMUP = 10.0       # s of driving before the window


def tokens(folder: Path, pages: int) -> tuple[list[str], str]:
    """A tokens file with one operator a page (pupil00 ...) and a viewer; the pages' tokens, the viewer's."""
    made = [f'scale-{i:02d}-{secrets.token_hex(8)}' for i in range(pages)]
    viewer = f'scale-viewer-{secrets.token_hex(8)}'
    (folder / 'tokens.toml').write_text(''.join(
        f'[[tokens]]\nname = "pupil{i:02d}"\nrole = "operator"\ntoken = "{t}"\n\n' for i, t in enumerate(made))
        + f'[[tokens]]\nname = "watcher"\nrole = "viewer"\ntoken = "{viewer}"\n')
    return made, viewer


class Owners:
    """Who each gateway announces as the stations' owners (its /rosgate/stations, followed on a
    websocket of its own, not through nginx). A fleet answers a claim from its gateway's memory
    and settles a clash in PostgreSQL after: a page let in before every gateway has heard the
    last claim may be given the same station (and lose it a moment later), the more so on a
    loaded machine. So the bench lets the next page in once every gateway announces the claim."""

    def __init__(self) -> None:
        self.owners: list[set[str]] = []
        self.changed = asyncio.Condition()
        self.tasks: list[asyncio.Task] = []
        self.sockets = []

    async def follow(self, urls: list[str]) -> None:
        for i, url in enumerate(urls):
            ws = await open_ws(url)
            self.sockets.append(ws)
            self.owners.append(set())
            await send_op(ws, {'op': 'subscribe', 'id': 'stations', 'topic': '/rosgate/stations',
                               'type': 'std_msgs/msg/String'})
            self.tasks.append(asyncio.create_task(self._read(i, ws)))

    async def _read(self, i: int, ws) -> None:
        try:
            async for frame in ws:
                msg = json.loads(frame)
                if msg.get('op') == 'publish':
                    async with self.changed:
                        self.owners[i] = set(json.loads(msg['msg']['data'])['owners'])
                        self.changed.notify_all()
        except ConnectionClosed:
            pass

    async def everywhere(self, station: str, timeout: float = 30.0) -> None:
        async with self.changed:
            await asyncio.wait_for(self.changed.wait_for(lambda: all(station in o for o in self.owners)), timeout)

    async def close(self) -> None:
        for t in self.tasks:
            t.cancel()
        for ws in self.sockets:
            await close_quietly(ws)


def proxy_block(port: int, gateways: list[int]) -> str:
    """docs/remote-lab.md's nginx block on ``port`` without TLS, to an upstream of the gateways."""
    site = guide_block()
    site = '\n'.join(line for line in site.splitlines() if 'ssl_certificate' not in line)
    site = (site.replace('listen 443 ssl;', f'listen 127.0.0.1:{port};')
            .replace('proxy_pass http://127.0.0.1:9090;', 'proxy_pass http://rosgate;'))
    assert 'proxy_pass http://rosgate;' in site and f'127.0.0.1:{port};' in site
    servers = ''.join(f'    server 127.0.0.1:{p};\n' for p in gateways)
    return f'upstream rosgate {{\n{servers}}}\n{site}'


def tree_cpu(pid: int) -> dict[int, float]:
    """CPU seconds of a process and of every process below it (PostgreSQL's backends, nginx's workers)."""
    out = {}
    for p in (pid, *descendants(pid)):
        sample = ProcMeter(p).sample()
        if sample is not None:
            out[p] = sample[1]
    return out


def tree_cpu_between(start: dict[int, float], end: dict[int, float]) -> float:
    """Seconds used between two tree_cpu samples (a process that came meanwhile: all of it)."""
    return sum(end[p] - start.get(p, 0.0) for p in end)


class Database:
    """The bench's PostgreSQL: its committed transactions and its processes."""

    def __init__(self, url: str) -> None:
        self.engine = sa.create_engine(url, poolclass=sa.pool.NullPool)
        with self.engine.connect() as c:
            backend = c.execute(sa.text('SELECT pg_backend_pid()')).scalar()
        with open(f'/proc/{backend}/stat') as f:
            self.pid = int(f.read().rsplit(')', 1)[1].split()[1])   # its parent: the postmaster

    def commits(self) -> int:
        """Committed transactions of the database so far (this query's own not counted)."""
        with self.engine.connect() as c:
            c.execute(sa.text('SELECT pg_stat_clear_snapshot()'))
            return c.execute(sa.text("SELECT xact_commit FROM pg_stat_database WHERE datname = 'rosgate'")).scalar() - 1


async def load(n: int, url: str, pages: int, folder: Path, db: Database, minutes: float, warmup: float,
               log) -> dict:
    """One row: N gateways behind nginx, the lesson's pages through it."""
    made, viewer = tokens(folder, pages)
    owners = Owners()
    flags = ['--backend', 'sim', '--robot', 'turtlesim', '--fleet', str(pages), '--exclusive-control',
             '--auth', str(folder / 'tokens.toml'), '--db', url, '--trusted-proxies', '127.0.0.1']
    gateways = []
    try:
        for i in range(n):
            gateways.append(start_rosgate([*flags, '--programs-dir', str(folder / f'programs-{i}')]))
        ports = [int(g.url.rsplit(':', 1)[1].strip('/')) for g in gateways]
        port = free_port()
        proxy = folder / f'nginx-{n}'
        proxy.mkdir()
        with nginx(proxy, proxy_block(port, ports), port) as web:
            await owners.follow([f'{g.url}?token={viewer}' for g in gateways])
            meters = [ProcMeter(g.pid) for g in gateways]
            await asyncio.sleep(2.0)   # the gateways' start-up work done
            idle0 = [m.sample() for m in meters]
            t0 = time.monotonic()
            await asyncio.sleep(IDLE)
            idle = [ProcMeter.cpu_between(a, m.sample()) / (time.monotonic() - t0) for a, m in zip(idle0, meters)]
            lesson = Lesson(f'ws://127.0.0.1:{port}/', pages,
                            page_url=lambda index: f'ws://127.0.0.1:{port}/?token={made[index]}')
            ready: asyncio.Queue = asyncio.Queue()
            tasks = []
            try:
                for i in range(pages):   # one after the other: nginx deals them out in turn
                    tasks.append(asyncio.create_task(lesson.page(i, ready)))
                    lesson.namespaces.append(await next_station(ready, tasks))
                    await owners.everywhere(lesson.namespaces[-1])
                if len(set(lesson.namespaces)) != pages:
                    raise RuntimeError(f'two pages were given one station: {sorted(lesson.namespaces)}')
                log(f'  {n} gateway(s): {pages} pages driving, each on a station of its own; warm-up {warmup:g} s')
                await asyncio.sleep(warmup)
                lesson.minute = window = Minute(1)
                cpu0 = [m.sample() for m in meters]
                web0, pg0, commits0 = tree_cpu(web.pid), tree_cpu(db.pid), db.commits()
                busy0, client0, t0 = machine_busy_s(), time.process_time(), time.monotonic()
                await asyncio.sleep(60.0 * minutes)
                window.seconds = seconds = time.monotonic() - t0
                commits = db.commits() - commits0
                cpu = [ProcMeter.cpu_between(a, m.sample()) for a, m in zip(cpu0, meters)]
                web_cpu = tree_cpu_between(web0, tree_cpu(web.pid))
                pg_cpu = tree_cpu_between(pg0, tree_cpu(db.pid))
                client = time.process_time() - client0
                busy = machine_busy_s() - busy0
            finally:
                lesson.stop.set()
                await asyncio.gather(*tasks, return_exceptions=True)
    finally:
        await owners.close()
        for g in gateways:
            g.stop()
    fig = window.figures()
    lat = sorted(window.latencies)
    messages = fig['commands_per_s'] + fig['pose_per_s'] + fig['markers_per_s'] + len(lat) / seconds
    cores = sum(cpu) / seconds
    idle_cores = sum(idle)
    gateways_pct = [100 * c / seconds for c in cpu]
    own = sum(cpu) + web_cpu + pg_cpu + client
    return {
        'gateways': n, 'pages': pages, 'seconds': round(seconds, 1),
        'messages_per_s': round(messages), 'commands_per_s': round(fig['commands_per_s']),
        'gateway_cpu_pct': [round(p, 1) for p in gateways_pct], 'gateways_cpu_pct': round(100 * cores, 1),
        'per_core': round(messages / cores) if cores else None,
        'idle_cpu_pct': [round(100 * i, 1) for i in idle],
        'per_core_less_idle': round(messages / (cores - idle_cores)) if cores > idle_cores else None,
        'nginx_cpu_pct': round(100 * web_cpu / seconds, 1), 'postgres_cpu_pct': round(100 * pg_cpu / seconds, 1),
        'per_core_serving': round(messages * seconds / (sum(cpu) + web_cpu + pg_cpu)),
        'client_cpu_pct': round(100 * client / seconds, 1),
        'other_cpu_pct': round(max(0.0, 100 * (busy - own) / seconds), 1),
        'rosapi_p50_ms': percentile(lat, 50), 'rosapi_p95_ms': percentile(lat, 95),
        'rosapi_calls': len(lat), 'rosapi_failed': window.failed_calls,
        'pg_xact_per_s': round(commits / seconds, 2),
        'pg_xact_per_command': round(commits / max(1, window.commands), 4),
        'errors': lesson.errors[:5],
    }


def row_text(r: dict) -> str:
    return (f"{r['gateways']} gateway(s): {r['messages_per_s']} msg/s ({r['commands_per_s']} commands/s), "
            f"gateways' CPU {r['gateways_cpu_pct']} % {r['gateway_cpu_pct']} (idle {r['idle_cpu_pct']}), "
            f"{r['per_core']} msg/s per core ({r['per_core_less_idle']} less idle, {r['per_core_serving']} with nginx "
            f"and PostgreSQL); rosapi p50 "
            f"{fmt(r['rosapi_p50_ms'])} ms p95 {fmt(r['rosapi_p95_ms'])} ms ({r['rosapi_calls']} calls, "
            f"{r['rosapi_failed']} failed); nginx {r['nginx_cpu_pct']} %, PostgreSQL {r['postgres_cpu_pct']} %, "
            f"client {r['client_cpu_pct']} %, other {r['other_cpu_pct']} %; PostgreSQL {r['pg_xact_per_s']} "
            f"transactions/s, {r['pg_xact_per_command']} per command")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog='python -m tests.bench scale', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--gateways', type=int, nargs='+', default=[1, 2, 4], help='fleet sizes (default 1 2 4)')
    p.add_argument('--pages', type=int, default=30, help='pages and stations (default 30)')
    p.add_argument('--minutes', type=float, default=1.0, help='the window per fleet size (default 1)')
    p.add_argument('--warmup', type=float, default=WARMUP, help=f'seconds of driving first (default {WARMUP:g})')
    p.add_argument('--out', help='write the rows as JSON to this file')
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix='rosgate-scale-'))
    os.environ['XDG_DATA_HOME'] = str(folder / 'data')   # the gateways' data folder: one, as a fleet shares it
    server = postgres_server()
    url = next(server)
    db = Database(url)
    rows = []
    try:
        for n in args.gateways:
            row = asyncio.run(load(n, url, args.pages, folder, db, args.minutes, args.warmup, print))
            print(row_text(row), flush=True)
            if row['errors']:
                print(f"  unexpected frames: {row['errors']}", flush=True)
            rows.append(row)
    finally:
        db.engine.dispose()
        next(server, None)
    if args.out:
        with open(args.out, 'w') as f:
            json.dump({'argv': sys.argv[1:], 'rows': rows}, f, indent=1)
        print(f'wrote {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
