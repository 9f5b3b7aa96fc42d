"""Waiting for an event with a deadline (never a fixed sleep): one poll loop, for threads and coroutines."""

from __future__ import annotations

import asyncio
import time

TIMEOUT = 30.0    # seconds of patience for a gateway's or a browser's reaction (not a bar: a wait ends at
                  # the event; a 2-core machine at load 50 missed 10 s)
INTERVAL = 0.01   # seconds between polls


def _polls(predicate, timeout: float, interval: float, what: str):
    """Yields the pause before the next poll; returns predicate()'s first truthy value."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f'{what} not met within {timeout} s')
        yield interval


def wait_for(predicate, timeout: float = TIMEOUT, interval: float = INTERVAL, what: str = 'condition'):
    """Poll until predicate() is truthy; return its value, or fail with AssertionError after timeout."""
    polls = _polls(predicate, timeout, interval, what)
    try:
        while True:
            time.sleep(next(polls))
    except StopIteration as done:
        return done.value


async def until(predicate, timeout: float = TIMEOUT, interval: float = INTERVAL, what: str = 'condition'):
    """wait_for inside an event loop: awaits between polls, so the loop's callbacks run."""
    polls = _polls(predicate, timeout, interval, what)
    try:
        while True:
            await asyncio.sleep(next(polls))
    except StopIteration as done:
        return done.value
