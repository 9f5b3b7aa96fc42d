"""The run archive's write cost: 30 runs printing at 1 kHz, kept in the store.

    .venv/bin/python -m tests.bench runs                  # 30 s
    make bench ARGS="runs --seconds 10 --out runs.json"

Each of ``--runs`` runs (default 30) prints ``--rate`` lines a second (default 1000, a line of
about 40 bytes) for ``--seconds``, through the archive's own path (``Archive.line``, what the
supervisor calls for each line of a run's output; lines handed in each 10 ms), batched to the
store's thread every ``FLUSH`` s, into SQLite with WAL in a temporary folder; then every run ends
(``Archive.end``). The cost is the CPU time of this process (all its threads, the store's
included) over the wall time, in % of one core, with what the rest of the machine used meanwhile
beside it; the same loop with the lines dropped (no archive) runs first, and its cost is taken
off (``archive_pct_of_core``). The output is then read back from the store and compared with what
was printed.
"""

from __future__ import annotations

import argparse
import asyncio
import shutil
import sys
import tempfile
import time
from types import SimpleNamespace

from gateway.runs.archive import Archive
from gateway.store import Store

from .report import save
from .servers import machine_busy_s

TICK = 0.01     # s between the hand-ins of each run's lines


def fake_run(i: int) -> SimpleNamespace:
    """What the archive reads of a Run."""
    return SimpleNamespace(id=f'r{i:08x}', name=f'bench {i}', owner=f'student{i:02d}', who=f'student{i:02d}',
                           ns=f'/s{i:02d}', started=time.time(), state='running', ended=None, exit_code=None,
                           reason=None)


async def printing(going: list, rate: float, seconds: float, line) -> int:
    """Every run's lines at ``rate`` for ``seconds``, handed to ``line(run_id, text)``; lines a run."""
    per_tick = rate * TICK
    wall0 = time.monotonic()
    printed, owed, tick = 0, 0.0, wall0
    while time.monotonic() - wall0 < seconds:
        owed += per_tick
        n = int(owed)
        owed -= n
        for run in going:
            for k in range(printed, printed + n):
                line(run.id, f'step {k:07d}: x=1.2345 y=6.7890 ok\n')
        printed += n
        tick += TICK
        await asyncio.sleep(max(0.0, tick - time.monotonic()))
    return printed


async def write_load(folder: str, runs: int, rate: float, seconds: float, cap: int) -> dict:
    going = [fake_run(i) for i in range(1, runs + 1)]
    cpu0, wall0 = time.process_time(), time.monotonic()
    await printing(going, rate, seconds, lambda run_id, text: None)
    base_pct = 100 * (time.process_time() - cpu0) / (time.monotonic() - wall0)
    store = Store(f'sqlite:///{folder}/rosgate.db')
    archive = Archive(store, cap=cap, keep_days=1, keep_count=1000, keep_bytes=2**40)
    for run in going:
        archive.begin(run, 'print("hello")\n' * 20, 'python')
    await store.run(lambda c: None)
    cpu0, wall0, busy0 = time.process_time(), time.monotonic(), machine_busy_s()
    printed = await printing(going, rate, seconds, archive.line)
    for run in going:
        run.state, run.ended, run.exit_code = 'finished', time.time(), 0
        archive.end(run, None)
    await store.run(lambda c: None)     # the last batch written
    wall, cpu, busy = time.monotonic() - wall0, time.process_time() - cpu0, machine_busy_s() - busy0
    kept = await store.run(lambda c: Archive.output(c, going[0].id))
    size = store.size()
    archive.close()
    store.close()
    lines = kept.count('\n')
    return {'runs': runs, 'rate_hz': rate, 'seconds': round(wall, 1), 'lines_per_run': printed,
            'lines_per_s': round(runs * printed / wall), 'cpu_pct_of_core': round(100 * cpu / wall, 2),
            'printing_pct_of_core': round(base_pct, 2), 'archive_pct_of_core': round(100 * cpu / wall - base_pct, 2),
            'other_cpu_pct': round(100 * (busy - cpu) / wall, 1), 'db_bytes': size,
            'kept_lines_first_run': lines, 'cut': kept.rstrip('\n').rsplit('\n', 1)[-1].startswith('[output cut')}


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog='python -m tests.bench runs')
    p.add_argument('--runs', type=int, default=30, help='runs printing at once [%(default)s]')
    p.add_argument('--rate', type=float, default=1000.0, help='lines a second each [%(default)s]')
    p.add_argument('--seconds', type=float, default=30.0, help='of printing [%(default)s]')
    p.add_argument('--cap', type=int, default=2**20, help='--run-output-cap [%(default)s]')
    p.add_argument('--out', help='write the figures as JSON here')
    args = p.parse_args(argv)
    folder = tempfile.mkdtemp(prefix='rosgate-bench-runs-')
    try:
        w = asyncio.run(write_load(folder, args.runs, args.rate, args.seconds, args.cap))
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    print(f"run archive write: {w['runs']} runs printing at {w['rate_hz']:g} Hz for {w['seconds']} s "
          f"({w['lines_per_s']} lines/s): the archive {w['archive_pct_of_core']} % of a core ({w['cpu_pct_of_core']} % "
          f"with the printing loop's own {w['printing_pct_of_core']} %; other load {w['other_cpu_pct']} %), "
          f"database {w['db_bytes'] / 2**20:.1f} MiB; the first run's output read back: "
          f"{w['kept_lines_first_run']} lines{' (cut at the cap)' if w['cut'] else ''} of {w['lines_per_run']} printed")
    save(args.out, w)
    complete = w['cut'] or w['kept_lines_first_run'] == w['lines_per_run']
    return 0 if complete else 1


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
