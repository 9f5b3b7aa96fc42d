"""Flow helpers shared by the scenarios: a send window, fixed-rate publishing, readers."""

from __future__ import annotations

import asyncio
import itertools
import os
import time

from websockets.asyncio.client import ClientConnection
from websockets.exceptions import ConnectionClosed

from .client import is_publish

STALL_S = 1.0  # no delivery for this long with a full window: count the window as lost

_names = itertools.count()


def unique_topic(kind: str) -> str:
    return f"/bench/{kind}_{os.getpid()}_{next(_names)}"


class SendWindow:
    """At most `size` messages published and not yet delivered.

    A watchdog declares the window lost when nothing arrives for STALL_S, so a
    server that drops messages slows the publisher down but never deadlocks it.
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self.inflight = 0
        self.lost = 0
        self.last_progress = time.monotonic()
        self._waiter: asyncio.Future | None = None
        self._watchdog = asyncio.get_running_loop().create_task(self._watch())

    async def acquire(self) -> None:
        while self.inflight >= self.size:
            self._waiter = asyncio.get_running_loop().create_future()
            await self._waiter
        self.inflight += 1

    def release(self) -> None:
        self.last_progress = time.monotonic()
        if self.inflight > 0:
            self.inflight -= 1
        waiter = self._waiter
        if waiter is not None and not waiter.done():
            waiter.set_result(None)

    async def drain(self, timeout: float = STALL_S) -> None:
        deadline = time.monotonic() + timeout
        while self.inflight and time.monotonic() < deadline:
            await asyncio.sleep(0.005)

    async def _watch(self) -> None:
        while True:
            await asyncio.sleep(STALL_S / 4)
            if self.inflight and time.monotonic() - self.last_progress > STALL_S:
                self.lost += self.inflight
                self.inflight = 0
                self.last_progress = time.monotonic()
                if self._waiter is not None and not self._waiter.done():
                    self._waiter.set_result(None)

    def close(self) -> None:
        self._watchdog.cancel()


async def publish_at(ws: ClientConnection, make_frame, rate: float, until: float, start_seq: int) -> int:
    """Publish make_frame(seq) at `rate` Hz on an absolute schedule until `until`; next seq."""
    period = 1.0 / rate
    seq = start_seq
    next_at = time.monotonic()
    while next_at < until:
        delay = next_at - time.monotonic()
        if delay > 0:
            await asyncio.sleep(delay)
        await ws.send(make_frame(seq), text=True)
        seq += 1
        next_at += period
    return seq


async def read_frames(ws: ClientConnection, on_frame, statuses: list | None = None) -> None:
    """Call on_frame(frame, now_ns) for every delivery until the connection closes."""
    try:
        while True:
            frame = await ws.recv(decode=False)
            now = time.monotonic_ns()
            if is_publish(frame):
                on_frame(frame, now)
            elif statuses is not None and len(statuses) < 20:
                statuses.append(frame[:300].decode("utf-8", "replace"))
    except ConnectionClosed:
        pass


async def settle(predicate, timeout: float, step: float = 0.01) -> bool:
    """Wait until predicate() holds or timeout passes; whether it held."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        await asyncio.sleep(step)
    return True
