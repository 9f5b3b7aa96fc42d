"""What starting a robot-side run costs: from POST /api/runs to its first output.

    python -m tests.bench.run_start [--repeat 5]

Two programs, each run ``--repeat`` times on a fresh ``--allow-runs`` gateway, one run at a time:
``print``, whose first statement prints the time (POST to the interpreter running the program),
and ``runtime``, the IDE's generated form, which imports roslibpy, connects back to the gateway
and logs a line (POST to a program that can drive). Times are read from GET /api/runs/ID polled
every 5 ms, so each figure is late by up to 5 ms.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
import urllib.request
from pathlib import Path

from tests.conftest import GatewayProcess

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
    args = parser.parse_args()
    gw = GatewayProcess('--robot', 'turtlesim', '--allow-runs', '--runs-dir', tempfile.mkdtemp(prefix='rosgate-runs-'))
    try:
        once(gw, PRINT)   # warm the page cache
        for name, source in (('print', PRINT), ('runtime', RUNTIME)):
            seen, own = zip(*(once(gw, source) for _ in range(args.repeat)))
            ms = lambda xs: ' '.join(f'{1000 * x:.0f}' for x in xs)   # noqa: E731
            print(f'{name:8} POST -> first line in GET: median {1000 * statistics.median(seen):.0f} ms ({ms(seen)})')
            if own[0] is not None:
                print(f'{name:8} POST -> program running:   median {1000 * statistics.median(own):.0f} ms ({ms(own)})')
    finally:
        gw.stop()


if __name__ == '__main__':
    main()
