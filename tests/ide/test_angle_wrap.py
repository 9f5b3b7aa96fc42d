"""Angle wrapping in both runtimes returns at once for any number: a loop of 2*pi steps never ended
for 1e20 (a block that takes an angle froze the tab or the robot-side run). Each call runs in a
child process with a timeout, so a hang fails the test instead of blocking the suite."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from tests.support.process import ROOT

HANG = 30   # seconds; the closed form answers in microseconds, a loop over 1e20 never does

# (a, b, expected): the finite ones wrapped into (-pi, pi], the others nan
CASES = [
    (1e20, 0.0, math.remainder(1e20, 2 * math.pi)),
    (-1e20, 0.0, math.remainder(-1e20, 2 * math.pi)),
    (math.inf, 0.0, math.nan),
    (-math.inf, 0.0, math.nan),
    (math.nan, 0.0, math.nan),
    (0.0, math.inf, math.nan),
    (7.0, 0.0, 7.0 - 2 * math.pi),
    (-math.pi, 0.0, math.pi),
    (math.pi, 0.0, math.pi),
    (3 * math.pi, 0.0, math.pi),
    (0.1, 2 * math.pi - 0.1, 0.2),
]

PY = """
import json, math, sys, types
m = types.ModuleType("rosgate_runtime")
exec(compile(open(sys.argv[1]).read(), "rosgate_runtime.py", "exec"), m.__dict__)
a, b = float(sys.argv[2]), float(sys.argv[3])
d = m.angle_diff(a, b)
print(json.dumps(None if math.isnan(d) else d))
"""

JS = """
const [file, a, b] = process.argv.slice(1);
const u = await import(file);
const d = u.angleDiff(Number(a), Number(b));
console.log(JSON.stringify(Number.isNaN(d) ? null : d));
"""


def js_number(x: float) -> str:
    return 'NaN' if math.isnan(x) else ('Infinity' if x == math.inf else '-Infinity' if x == -math.inf else repr(x))


def answer(cmd: list[str]):
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=HANG, check=True).stdout
    except subprocess.TimeoutExpired:
        pytest.fail(f'no answer within {HANG} s: {cmd[-2:]}')
    return json.loads(out)


def check(got, expected):
    if math.isnan(expected):
        assert got is None, f'expected nan, got {got}'
    else:
        assert got == pytest.approx(expected, abs=1e-9)
        assert -math.pi < got <= math.pi


@pytest.mark.parametrize('a,b,expected', CASES)
def test_python_runtime(a, b, expected):
    check(answer([sys.executable, '-c', PY, str(ROOT / 'ide/runtime/rosgate_runtime.py'), repr(a), repr(b)]), expected)


@pytest.mark.parametrize('a,b,expected', CASES)
def test_javascript_runtime(a, b, expected):
    url = (ROOT / 'ide/runtime/util.js').as_uri()
    check(answer(['node', '--input-type=module', '-e', JS, url, js_number(a), js_number(b)]), expected)
