"""Processes of the tests: a rosgate command started with its address read from its startup line,
the gateway of this checkout on a free loopback port, and a process's memory figures."""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LINE = re.compile(r'websocket (wss?)://([^:/]+|\[[^\]]+\]):(\d+)(/\S*)')
NODE = re.compile(r' node (\S+)')


START = 150   # s: a gateway's start-up line on a 2-core machine at load 100 (imports alone took 13 s at load 7)


class Started:
    """A rosgate command started in ``cwd``, its address read from its startup line. Its log goes
    to a file: a pipe nobody reads would block a gateway that logs a lot. A command that exits
    fails at once; one that says nothing fails after ``timeout`` (patience, not a bar: a busy
    machine's full-suite run saw 61 gateways miss a deadline of 30 s)."""

    def __init__(self, cmd: list, cwd: Path = ROOT, env: dict | None = None, timeout: float = START):
        self.log = tempfile.TemporaryFile(mode='w+', prefix='rosgate-log-')
        self.proc = subprocess.Popen([str(c) for c in cmd], cwd=cwd, stdout=subprocess.PIPE, stderr=self.log,
                                     text=True, env=env)
        self.line = self._read_line(timeout)
        m = LINE.search(self.line)
        if not m:
            self.stop()
            raise RuntimeError(f'rosgate did not start: {self.line!r}\n{self.log_text()[-4000:]}')
        scheme, self.host, port, self.path = m.groups()
        self.port = int(port)
        self.ws_url = f'{scheme}://{self.host}:{self.port}{self.path}'
        self.http_url = f"{'https' if scheme == 'wss' else 'http'}://{self.host}:{self.port}/"
        self.node = NODE.search(self.line).group(1) if NODE.search(self.line) else None   # its ROS node
        self.pid = self.proc.pid

    def _read_line(self, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            ready, _, _ = select.select([self.proc.stdout], [], [], 0.2)
            if ready:
                return self.proc.stdout.readline()
            if self.proc.poll() is not None:
                break
        return ''

    def log_text(self) -> str:
        """What the gateway has logged so far (its stderr)."""
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    @property
    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 15) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode


class GatewayProcess(Started):
    """``python -m gateway --port 0`` of this checkout on 127.0.0.1, with a programs folder of its own
    inside a folder of its own (tests that look beside the library see only what the gateway did)."""

    def __init__(self, *args: str, env: dict | None = None):
        self.home = tempfile.mkdtemp(prefix='rosgate-gateway-')
        self.programs_dir = os.path.join(self.home, 'programs')
        self.data_home = os.path.join(self.home, 'data')   # its store, runs, recordings: its own
        super().__init__([sys.executable, '-m', 'gateway', '--port', '0', '--address', '127.0.0.1',
                          '--programs-dir', self.programs_dir, *args],
                         env={**os.environ, 'XDG_DATA_HOME': self.data_home, **(env or {})})


def proc_bytes(pid: int, field: str = 'VmRSS') -> int:
    """A memory figure of a process from /proc/PID/status (VmRSS, VmHWM, ...), in bytes."""
    with open(f'/proc/{pid}/status') as f:
        for line in f:
            if line.startswith(f'{field}:'):
                return int(line.split()[1]) * 1024
    raise AssertionError(f'no {field} for {pid}')


def uids(pid: int) -> list[int]:
    """Real, effective, saved and filesystem uid of a process (/proc/PID/status)."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('Uid:'):
            return [int(v) for v in line.split()[1:]]
    return []


def descendants(pid: int) -> list[int]:
    """Every process below pid (children, their children ...), from /proc/PID/task/*/children."""
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        try:
            children = [int(c) for t in os.listdir(f'/proc/{p}/task')
                        for c in Path(f'/proc/{p}/task/{t}/children').read_text().split()]
        except OSError:
            continue
        found += children
        todo += children
    return found
