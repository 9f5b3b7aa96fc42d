"""One robot-side run's record and its output pipe.

``Run``: its id, namespace, state, starter and the tail of its output (what GET /api/runs/ID shows).
``RunOutput``: the process's stdout and stderr (one pipe) cut into lines up to the output cap.
Output past the cap (4 MiB) is not cut into lines: every DRAIN_PERIOD what the pipe holds is read
and thrown away, so a program that floods its output blocks on a full pipe in between instead of
keeping a core of the gateway busy (reading and splitting it as fast as it came took 97 % of one).
"""

from __future__ import annotations

import asyncio
import fcntl
import os
import secrets
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from .cgroups import RunCgroup

OUTPUT_TAIL = 64 * 1024        # bytes of output kept for GET /api/runs/ID
LINE_LIMIT = 4096              # longer lines are cut
DRAIN_PERIOD = 0.1             # s between the reads that drop output past the cap
DRAIN_READS = 4                # of PIPE_SIZE each: output past the cap flows at up to 40 MiB/s
PIPE_SIZE = 2**20


@dataclass(frozen=True)
class RunLimits:
    timeout: float = 600.0          # s, when the request gives none
    max_timeout: float = 3600.0
    cpu_seconds: int = 600
    memory_mb: int = 1024           # address space; Python with roslibpy needs a few hundred MiB
    open_files: int = 256
    processes: int = 512            # threads and processes of the run (its user namespace and cgroup)
    cpus: float = 1.0               # share of the machine's cores with a cgroup
    output_bytes: int = 4 * 2**20   # published per run; past it output is dropped at the pipe


class Run:
    def __init__(self, id: str, name: str, ns: str, timeout: float, workdir: Path):
        self.id, self.name, self.ns, self.timeout, self.workdir = id, name, ns, timeout, workdir
        self.key = secrets.token_urlsafe(24)
        self.state, self.exit_code, self.reason = 'starting', None, None
        self.started, self.ended = time.time(), None
        self.tail: deque[str] = deque()
        self.tail_bytes = 0
        self.sessions: list = []
        self.ending: str | None = None     # 'stopped' or 'timed_out' once we end it
        self.pid: int | None = None        # also its process group
        self.done: asyncio.Future = asyncio.get_running_loop().create_future()
        self.timers: list[asyncio.TimerHandle] = []
        self.output_pub = self.state_pub = None
        self.memory_error = False
        self.role: str | None = None         # the starter's role, given to the run's connection
        self.person: str | None = None       # who started it: the run drives for them (rules.stations)
        self.owner: str | None = None        # the starter's key (None: auth is off)
        self.who: str | None = None          # the starter's name, as pages show it
        self.recorder = None                 # () -> (MCAP path, bytes): finishes the run's recording
        self.cgroup: RunCgroup | None = None
        self.kind = 'python'                 # what the source is: runs.node.KIND for a ROS 2 node

    def summary(self) -> dict:
        return {'id': self.id, 'name': self.name, 'ns': self.ns, 'state': self.state,
                'exit_code': self.exit_code, 'reason': self.reason, 'started': self.started,
                'ended': self.ended, 'timeout': self.timeout, 'owner': self.who,
                'recorded': self.recorder is not None}

    def detail(self) -> dict:
        return {**self.summary(), 'output': ''.join(self.tail)}

    def keep(self, line: str) -> None:
        self.tail.append(line)
        self.tail_bytes += len(line)
        while self.tail_bytes > OUTPUT_TAIL and len(self.tail) > 1:
            self.tail_bytes -= len(self.tail.popleft())


class RunOutput(asyncio.SubprocessProtocol):
    """The process's stdout and stderr (one pipe), cut into lines until ``limit`` bytes came (then
    ``on_limit()``; the rest is read in large chunks now and then and thrown away), and when it ends."""

    def __init__(self, on_line, on_limit, limit: int, loop):
        self.on_line, self.on_limit, self.limit, self.loop = on_line, on_limit, limit, loop
        self.pending = b''
        self.received = 0
        self.pipe = None
        self.drain: asyncio.TimerHandle | None = None
        self.exited, self.eof = loop.create_future(), loop.create_future()

    def connection_made(self, transport) -> None:
        self.pipe = transport.get_pipe_transport(1)
        try:      # fewer, larger reads (1 MiB is what an unprivileged process may ask by default)
            fcntl.fcntl(self.pipe.get_extra_info('pipe').fileno(), fcntl.F_SETPIPE_SZ, PIPE_SIZE)
        except (OSError, AttributeError):
            pass

    def pipe_data_received(self, fd: int, data: bytes) -> None:
        if self.received > self.limit:
            self._drop()
            return
        self.received += len(data)
        over = self.received > self.limit
        if over:
            data = data[:len(data) - (self.received - self.limit)]
        self.pending += data
        *lines, self.pending = self.pending.split(b'\n')
        for line in lines:
            self.on_line(line[:LINE_LIMIT].decode('utf-8', 'replace') + '\n')
        if len(self.pending) > LINE_LIMIT:
            self.on_line(self.pending[:LINE_LIMIT].decode('utf-8', 'replace') + '\n')
            self.pending = b''
        if over:
            self.pending = b''
            self.on_limit()
            self._drop()

    def _drop(self) -> None:
        """Past the limit: read again (and drop what comes) only after DRAIN_PERIOD."""
        if self.pipe is not None and self.drain is None:
            self.pipe.pause_reading()
            self.drain = self.loop.call_later(DRAIN_PERIOD, self._resume)

    def _resume(self) -> None:
        """Drop what the pipe holds (up to a few MiB) with reads of our own, then let the transport
        read again: the next thing it reads (or its end) comes to pipe_data_received."""
        self.drain = None
        if self.pipe.is_closing():
            return
        pipe = self.pipe.get_extra_info('pipe')   # None on uvloop: then its transport reads, and we drop that
        try:
            for _ in range(DRAIN_READS if pipe is not None else 0):
                if not os.read(pipe.fileno(), PIPE_SIZE):
                    break             # its end: the transport sees it too
        except OSError:               # BlockingIOError: empty
            pass
        self.pipe.resume_reading()

    def pipe_connection_lost(self, fd: int, exc) -> None:
        if self.drain is not None:
            self.drain.cancel()
        if self.pending:
            self.on_line(self.pending.decode('utf-8', 'replace') + '\n')
            self.pending = b''
        if not self.eof.done():
            self.eof.set_result(None)

    def process_exited(self) -> None:
        if not self.exited.done():
            self.exited.set_result(None)
