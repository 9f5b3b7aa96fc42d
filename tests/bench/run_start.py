"""What starting a robot-side run costs: from POST /api/runs to its first output.

    python -m tests.bench.run_start [--repeat 5] [--compare DIR]

``--compare DIR`` starts a second gateway from another checkout (DIR, e.g. one made with
``git worktree add DIR <commit>``) with the same interpreter, and takes its runs in turn with this
checkout's, one each, so both see the same load of a busy machine.

Two programs, each run ``--repeat`` times on a fresh ``--allow-runs`` gateway, one run at a time:
``print``, whose first statement prints the time (POST to the interpreter running the program),
and ``runtime``, the IDE's generated form, which imports roslibpy, connects back to the gateway
and logs a line (POST to a program that can drive). Times are read from GET /api/runs/ID polled
every 5 ms, so each figure is late by up to 5 ms.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

from tests.support.process import GatewayProcess, Started

ROOT = Path(__file__).resolve().parents[2]
PRINT = 'import time\nprint("up %.6f" % time.time(), flush=True)\n'
RUNTIME = ((ROOT / 'ide' / 'runtime' / 'rosgate_runtime.py').read_text()
           + '\n\ndef main():\n    rt.log("up")\n\nif __name__ == "__main__":\n    run(main)\n')


def call(gw, method: str, path: str, body=None) -> dict:
    req = urllib.request.Request(gw.http_url.rstrip('/') + path, method=method,
                                 data=None if body is None else json.dumps(body).encode())
    req.add_header('Content-Type', 'application/json')
    with urllib.request.urlopen(req, timeout=10) as res:
        return json.loads(res.read())


def once(gw, source: str) -> tuple[float, float | None]:
    """Seconds from POST to the first line in GET, and (print) to the program's own first statement."""
    t0 = time.time()
    run_id = call(gw, 'POST', '/api/runs', {'source': source, 'name': 'bench'})['id']
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        run = call(gw, 'GET', f'/api/runs/{run_id}')
        if 'up' in run['output']:
            seen = time.time() - t0
            first = run['output'].split('up', 1)[1].split()
            own = float(first[0]) - t0 if first and first[0][0].isdigit() else None
            while run['state'] in ('starting', 'running'):
                time.sleep(0.005)
                run = call(gw, 'GET', f'/api/runs/{run_id}')
            return seen, own
        if run['state'] not in ('starting', 'running'):
            raise RuntimeError(f'run ended before its first line: {run}')
        time.sleep(0.005)
    raise RuntimeError('no output within 60 s')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeat', type=int, default=5)
    parser.add_argument('--compare', type=Path, help='a checkout whose gateway runs in turn with this one\'s')
    args = parser.parse_args()
    flags = ['--robot', 'turtlesim', '--allow-runs']
    gateways = {'this': GatewayProcess(*flags, '--runs-dir', tempfile.mkdtemp(prefix='rosgate-runs-'))}
    try:
        if args.compare is not None:
            gateways['compare'] = Started(
                [sys.executable, '-m', 'gateway', '--port', '0', '--address', '127.0.0.1', *flags, '--runs-dir',
                 tempfile.mkdtemp(prefix='rosgate-runs-')], cwd=args.compare.resolve(),
                env={**os.environ, 'XDG_DATA_HOME': tempfile.mkdtemp(prefix='rosgate-data-')})
        for gw in gateways.values():
            once(gw, PRINT)   # warm the page cache
        for name, source in (('print', PRINT), ('runtime', RUNTIME)):
            times = {which: [] for which in gateways}
            for _ in range(args.repeat):
                for which, gw in gateways.items():
                    times[which].append(once(gw, source))
            for which, got in times.items():
                seen, own = zip(*got)
                ms = lambda xs: ' '.join(f'{1000 * x:.0f}' for x in xs)   # noqa: E731
                label = f'{name:8} {which:8}' if len(gateways) > 1 else f'{name:8}'
                print(f'{label} POST -> first line in GET: median {1000 * statistics.median(seen):.0f} ms ({ms(seen)})')
                if own[0] is not None:
                    print(f'{label} POST -> program running:   median {1000 * statistics.median(own):.0f} ms '
                          f'({ms(own)})')
    finally:
        for gw in gateways.values():
            gw.stop()


if __name__ == '__main__':
    main()
