"""An emulated home link for tests: two network namespaces joined packet by packet.

This kernel has no netem, so the link is a user-space forwarder: each namespace gets a TUN
device (``client`` 10.31.N.1, ``server`` 10.31.N.2, point to point) and a thread per direction
moves IP packets from one to the other, adding what a home line does: a one-way ``delay`` with
``jitter`` (uniform, order kept), random ``loss``, a ``rate`` limit (bytes/s) behind a ``buffer``
(bytes, tail drop when full) and ``freeze(seconds)``, an outage that drops everything. TCP then
behaves as it does at home: retransmissions, backoff, a backlog delivered when the link returns.

    with NetLink(delay=0.15, jitter=0.05, loss=0.02) as link:
        gw = link.start_gateway('--robot', 'turtlesim')      # inside the server namespace
        with link.inside('client'):                          # sockets made here are the client's
            ros = Raw(gw.ws_url)
        link.freeze(2.0)

Needs root (CI runs as root) for ``ip netns`` and /dev/net/tun; everything it makes is gone on
exit (the namespaces and their devices). ``inside(ns)`` moves only the calling thread.
"""

from __future__ import annotations

import ctypes
import fcntl
import heapq
import itertools
import os
import random
import select
import struct
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

from tests.support.process import ROOT, Started

CLONE_NEWNET = 0x40000000
TUNSETIFF = 0x400454CA
IFF_TUN, IFF_NO_PI = 0x0001, 0x1000
_libc = ctypes.CDLL(None, use_errno=True)
_count = itertools.count(1)


def available() -> str | None:
    """Why links cannot be made here (None when they can)."""
    if os.geteuid() != 0:
        return 'needs root (ip netns, /dev/net/tun)'
    if not os.path.exists('/dev/net/tun'):
        return 'no /dev/net/tun'
    return None


def _setns(fd: int) -> None:
    if _libc.setns(fd, CLONE_NEWNET) != 0:
        err = ctypes.get_errno()
        raise OSError(err, os.strerror(err))


def _ip(*args: str) -> None:
    subprocess.run(['ip', *args], check=True, capture_output=True, timeout=10)


class Direction:
    """One way of the link: packets read from ``src`` are written to ``dst`` when due."""

    def __init__(self, link: NetLink, src: int, dst: int, seed: int):
        self.link, self.src, self.dst = link, src, dst
        self.rng = random.Random(seed)
        self.queue: list[tuple[float, int, bytes]] = []   # (due, seq, packet)
        self.seq = itertools.count()
        self.sent_until = 0.0      # when the rate limiter has sent what it holds
        self.last_due = 0.0        # order is kept: no packet overtakes another
        self.queued = 0            # bytes waiting for the rate limiter
        self.dropped = self.passed = 0

    def take(self, packet: bytes, now: float) -> None:
        link = self.link
        if now < link.frozen_until or self.rng.random() < link.loss:
            self.dropped += 1
            return
        start = now
        if link.rate:
            backlog = max(0.0, self.sent_until - now) * link.rate
            if backlog + len(packet) > link.buffer:
                self.dropped += 1
                return
            start = max(now, self.sent_until) + len(packet) / link.rate
            self.sent_until = start
        due = start + link.delay + self.rng.uniform(-link.jitter, link.jitter)
        due = max(due, self.last_due)
        self.last_due = due
        heapq.heappush(self.queue, (due, next(self.seq), packet))

    def run(self) -> None:
        while not self.link.closed:
            now = time.monotonic()
            while self.queue and self.queue[0][0] <= now:
                _, _, packet = heapq.heappop(self.queue)
                if now < self.link.frozen_until:   # an outage also drops what was on the wire
                    self.dropped += 1
                    continue
                try:
                    os.write(self.dst, packet)
                    self.passed += 1
                except OSError:
                    self.dropped += 1
            wait = min(0.05, self.queue[0][0] - now) if self.queue else 0.05
            ready, _, _ = select.select([self.src], [], [], max(0.0, wait))
            if ready:
                try:
                    packet = os.read(self.src, 65536)
                except OSError:
                    continue
                self.take(packet, time.monotonic())


class NetLink:
    def __init__(self, delay: float = 0.0, jitter: float = 0.0, loss: float = 0.0,
                 rate: float | None = None, buffer: int = 64 * 1024, seed: int = 31):
        self.delay, self.jitter, self.loss, self.rate, self.buffer = delay, jitter, loss, rate, buffer
        self.seed = seed
        n = next(_count)
        tag = f'{os.getpid() % 100000}x{n}'
        self.names = {'client': f'rgc{tag}', 'server': f'rgs{tag}'}
        subnet = 100 + (os.getpid() + n) % 150
        self.addr = {'client': f'10.31.{subnet}.1', 'server': f'10.31.{subnet}.2'}
        self.frozen_until = 0.0
        self.closed = False
        self.fds: dict[str, int] = {}
        self.threads: list[threading.Thread] = []
        self.directions: list[Direction] = []
        self.started: list[Started] = []

    # --- making and unmaking ----------------------------------------------------------------

    def __enter__(self) -> NetLink:
        try:
            for side, name in self.names.items():
                peer = self.addr['server' if side == 'client' else 'client']
                _ip('netns', 'add', name)
                _ip('-n', name, 'link', 'set', 'lo', 'up')
                _ip('-n', name, 'tuntap', 'add', 'dev', 'tun0', 'mode', 'tun')
                _ip('-n', name, 'addr', 'add', self.addr[side], 'peer', peer, 'dev', 'tun0')
                _ip('-n', name, 'link', 'set', 'tun0', 'up')
                with self.inside(side):
                    fd = os.open('/dev/net/tun', os.O_RDWR)
                    fcntl.ioctl(fd, TUNSETIFF, struct.pack('16sH', b'tun0', IFF_TUN | IFF_NO_PI))
                self.fds[side] = fd
            up = Direction(self, self.fds['client'], self.fds['server'], self.seed)
            down = Direction(self, self.fds['server'], self.fds['client'], self.seed + 1)
            self.directions = [up, down]
            for d in self.directions:
                t = threading.Thread(target=d.run, daemon=True, name='netlink')
                t.start()
                self.threads.append(t)
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc) -> None:
        for proc in self.started:
            proc.stop()
        self.closed = True
        for t in self.threads:
            t.join(2)
        for fd in self.fds.values():
            os.close(fd)
        for name in self.names.values():
            subprocess.run(['ip', 'netns', 'del', name], capture_output=True, timeout=10)

    # --- using ------------------------------------------------------------------------------

    @contextmanager
    def inside(self, side: str):
        """Run the block in namespace ``side`` ('client' or 'server'): sockets it makes belong there."""
        back = os.open(f'/proc/thread-self/ns/net', os.O_RDONLY)
        target = os.open(f'/var/run/netns/{self.names[side]}', os.O_RDONLY)
        try:
            _setns(target)
            yield
        finally:
            _setns(back)
            os.close(back)
            os.close(target)

    def command(self, side: str, *cmd) -> list[str]:
        """``cmd`` run inside namespace ``side``."""
        return ['ip', 'netns', 'exec', self.names[side], *[str(c) for c in cmd]]

    def freeze(self, seconds: float) -> float:
        """An outage from now on: every packet either way is dropped for ``seconds``. Returns
        when it ends (time.monotonic())."""
        self.frozen_until = time.monotonic() + seconds
        return self.frozen_until

    @property
    def frozen(self) -> bool:
        return time.monotonic() < self.frozen_until

    def start_gateway(self, *flags: str, timeout: float = 60) -> Started:
        """``python -m gateway`` of this checkout in the server namespace, on its link address,
        with a data folder of its own."""
        import tempfile
        home = tempfile.mkdtemp(prefix='rosgate-netlink-')
        env = {**os.environ, 'XDG_DATA_HOME': os.path.join(home, 'data'), 'PYTHONPATH': str(ROOT)}
        gw = Started(self.command('server', sys.executable, '-m', 'gateway', '--port', '0',
                                  '--address', self.addr['server'],
                                  '--programs-dir', os.path.join(home, 'programs'), *flags),
                     env=env, timeout=timeout)
        self.started.append(gw)
        return gw

    def chromium_wrapper(self, chromium: str, folder: Path) -> Path:
        """An executable that starts ``chromium`` in the client namespace (for Playwright's
        executable_path: it talks to the browser over pipes, which pass through)."""
        path = folder / f'chromium-{self.names["client"]}'
        path.write_text(f'#!/bin/sh\nexec ip netns exec {self.names["client"]} {chromium} "$@"\n')
        path.chmod(0o755)
        return path
