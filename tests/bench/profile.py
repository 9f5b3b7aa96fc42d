"""Sampling the server under test with py-spy, and a text summary of the samples.

    python -m tests.bench --scenarios throughput --py-spy /tmp/rosgate.txt
records the server (rosgate or --server-pid) for the whole run; a `.svg` name
gives a flame graph instead of collapsed stacks. `python -m tests.bench.profile
FILE` prints the functions with the most samples, self and inclusive.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
from collections import Counter
from pathlib import Path


class PySpy:
    def __init__(self, pid: int, out: str, rate: int = 250) -> None:
        exe = shutil.which("py-spy") or str(Path(sys.executable).parent / "py-spy")
        if not Path(exe).exists():
            raise SystemExit("py-spy is not installed (pip install py-spy)")
        fmt = "flamegraph" if out.endswith(".svg") else "raw"
        self.out = out
        self.proc = subprocess.Popen(
            [exe, "record", "--pid", str(pid), "--rate", str(rate), "--format", fmt,
             "--output", out, "--nonblocking", "--threads"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)

    def stop(self) -> str:
        self.proc.send_signal(signal.SIGINT)
        try:
            _out, err = self.proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            _out, err = self.proc.communicate()
        if not Path(self.out).exists():
            return f"py-spy wrote nothing: {err.strip()[-500:]}"
        if self.out.endswith(".svg"):
            return f"flame graph in {self.out}"
        return summary(self.out)


def summary(path: str, top: int = 25) -> str:
    own: Counter[str] = Counter()
    inclusive: Counter[str] = Counter()
    total = 0
    for line in Path(path).read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        if not stack or not count.isdigit():
            continue
        n = int(count)
        total += n
        frames = [_short(f) for f in stack.split(";")]
        own[frames[-1]] += n
        for frame in set(frames):
            inclusive[frame] += n
    if not total:
        return f"no samples in {path}"
    lines = [f"{total} samples in {path}", "", "self %   function"]
    lines += [f"{100 * n / total:6.1f}   {name}" for name, n in own.most_common(top)]
    lines += ["", "incl %   function"]
    lines += [f"{100 * n / total:6.1f}   {name}" for name, n in inclusive.most_common(top)]
    return "\n".join(lines)


def _short(frame: str) -> str:
    """'func (pkg/mod.py:123)' without the line number, so a function is one row."""
    name, _, where = frame.partition(" (")
    where = where.rstrip(")").rsplit(":", 1)[0]
    for marker in ("site-packages/", "/lib/python3"):
        if marker in where:
            where = where.split(marker, 1)[1]
    return f"{name} ({where})" if where else name


if __name__ == "__main__":
    print(summary(sys.argv[1]))
