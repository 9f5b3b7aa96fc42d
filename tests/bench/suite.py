"""What the test suite costs, per file: the CPU-seconds of each test process's whole tree (gateways,
browsers, node, PostgreSQL ...) and the gateways and browsers started, as ``pytest --cost DIR``
recorded them (tests/support/cost.py). CPU-seconds hold on a busy machine; wall times do not, so the
machine's load is printed beside them.

    .venv/bin/python -m pytest -q -n 2 --no-loadscope-reorder --cost /tmp/cost tests
    .venv/bin/python -m tests.bench suite /tmp/cost                  # per file, the costliest first
    .venv/bin/python -m tests.bench suite /tmp/cost --before /tmp/cost-old --top 30
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

KINDS = ('gateway', 'chromium', 'playwright', 'firefox', 'webkit', 'node', 'postgres', 'child', 'pytest')
BROWSERS = ('chromium', 'firefox', 'webkit')


def load(folder: str) -> list[dict]:
    rows = []
    for path in sorted(Path(folder).glob('cost-*.jsonl')):
        for line in path.read_text().splitlines():
            if line.strip():
                row = json.loads(line)
                row['worker'] = path.stem[len('cost-'):]
                rows.append(row)
    if not rows:
        raise SystemExit(f'no cost-*.jsonl in {folder}')
    return rows


def per_file(rows: list[dict]) -> dict[str, dict]:
    files: dict[str, dict] = defaultdict(lambda: {'tests': 0, 'wall': 0.0, 'cpu': 0.0, 'kinds': defaultdict(float),
                                                  'started': defaultdict(int), 'failed': 0})
    for r in rows:
        f = files[r['file']]
        f['tests'] += 1
        f['wall'] += r['wall']
        f['cpu'] += r['cpu']
        for k, v in r['kinds'].items():
            f['kinds'][k] += v
        for k, v in r['started'].items():
            f['started'][k] += v
        f['failed'] += r['outcome'] != 'passed' and 'skipped' not in r['outcome']
    return files


def summary(rows: list[dict]) -> dict:
    kinds: dict[str, float] = defaultdict(float)
    started: dict[str, int] = defaultdict(int)
    workers: dict[str, float] = defaultdict(float)
    for r in rows:
        for k, v in r['kinds'].items():
            kinds[k] += v
        for k, v in r['started'].items():
            started[k] += v
        workers[r['worker']] += r['wall']
    loads = [r['load'][0] for r in rows] + [r['load_end'][0] for r in rows]
    return {'tests': len(rows), 'cpu': sum(r['cpu'] for r in rows), 'kinds': dict(kinds),
            'started': dict(started), 'workers': dict(workers),
            'failed': [r['test'] for r in rows if r['outcome'] != 'passed' and 'skipped' not in r['outcome']],
            'load': (min(loads), sum(loads) / len(loads), max(loads))}


def _kinds(kinds: dict) -> str:
    top = sorted(kinds.items(), key=lambda kv: -kv[1])
    return ' '.join(f'{k} {v:.0f}' for k, v in top if v >= 0.5)


def report(rows: list[dict], before: list[dict] | None, top: int) -> str:
    out = []
    s = summary(rows)
    out.append(f"{s['tests']} tests, {s['cpu']:.0f} CPU-s in the test processes' trees; "
               f"wall per test process {', '.join(f'{w} {v / 60:.1f} min' for w, v in sorted(s['workers'].items()))}; "
               f"load (1 min) min {s['load'][0]:.1f} mean {s['load'][1]:.1f} max {s['load'][2]:.1f}")
    out.append('by kind: ' + ', '.join(f'{k} {v:.0f} s ({100 * v / s["cpu"]:.0f} %)'
                                       for k, v in sorted(s['kinds'].items(), key=lambda kv: -kv[1]) if v >= 1))
    out.append('started: ' + ', '.join(f'{k} {v}' for k, v in sorted(s['started'].items())))
    if before:
        b = summary(before)
        out.append(f"before: {b['tests']} tests, {b['cpu']:.0f} CPU-s; started: "
                   + ', '.join(f'{k} {v}' for k, v in sorted(b['started'].items()))
                   + '; by kind: ' + ', '.join(f'{k} {v:.0f}' for k, v in sorted(b['kinds'].items(), key=lambda kv: -kv[1])
                                               if v >= 1))
    if s['failed']:
        out.append(f"not passed ({len(s['failed'])}): " + ', '.join(s['failed']))
    files = per_file(rows)
    old = per_file(before) if before else {}
    out.append('')
    head = f"{'file':52} {'tests':>5} {'wall s':>7} {'CPU s':>7}"
    if before:
        head += f" {'before':>7}"
    out.append(head + f" {'gw':>3} {'brw':>3}  CPU by kind")
    total_cpu = sum(f['cpu'] for f in files.values())
    for name, f in sorted(files.items(), key=lambda kv: -kv[1]['cpu'])[:top]:
        line = f"{name:52} {f['tests']:5} {f['wall']:7.0f} {f['cpu']:7.0f}"
        if before:
            line += f" {old[name]['cpu']:7.0f}" if name in old else f" {'-':>7}"
        browsers = sum(f['started'].get(b, 0) for b in BROWSERS)
        line += f" {f['started'].get('gateway', 0):3} {browsers:3}  {_kinds(f['kinds'])}"
        out.append(line + (f"  [{f['failed']} not passed]" if f['failed'] else ''))
    rest = sorted(files.items(), key=lambda kv: -kv[1]['cpu'])[top:]
    if rest:
        out.append(f"{len(rest)} more files: {sum(f['cpu'] for _, f in rest):.0f} CPU-s "
                   f"({100 * sum(f['cpu'] for _, f in rest) / total_cpu:.0f} %)")
    folders: dict[str, list] = defaultdict(lambda: [0.0, 0.0, 0, 0])
    for name, f in files.items():
        d = folders['/'.join(name.split('/')[:2])]
        d[0] += f['cpu']
        d[1] += f['wall']
        d[2] += f['started'].get('gateway', 0)
        d[3] += sum(f['started'].get(b, 0) for b in BROWSERS)
    out.append('')
    out.append('by folder: ' + '; '.join(f'{k} {v[0]:.0f} CPU-s, {v[1]:.0f} s, {v[2]} gw, {v[3]} browsers'
                                          for k, v in sorted(folders.items(), key=lambda kv: -kv[1][0])))
    return '\n'.join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog='python -m tests.bench suite', description=__doc__.split('\n\n')[0])
    ap.add_argument('folder', help='the --cost DIR of a pytest run')
    ap.add_argument('--before', help='the --cost DIR of an earlier run, for a before/after column')
    ap.add_argument('--top', type=int, default=40, help='files listed (the costliest)')
    args = ap.parse_args(argv)
    print(report(load(args.folder), load(args.before) if args.before else None, args.top))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
