"""The backend contract suite's checks: whether rclpy imports, equality where NaN equals NaN,
and a publish repeated until a fresh subscription delivers."""

from __future__ import annotations

import asyncio
import math


def same(a, b) -> bool:
    """Equality where NaN equals NaN (also inside lists and dicts)."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


async def roundtrip(publisher, queue: asyncio.Queue, msg: dict, timeout: float = 5.0) -> dict:
    """Publish until the subscription delivers (a fresh ROS subscription may need a moment to
    match); the first message received."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while True:
        publisher.publish(msg)
        try:
            return await asyncio.wait_for(queue.get(), 0.2)
        except asyncio.TimeoutError:
            if loop.time() > deadline:
                raise AssertionError(f'no message on {publisher.topic} within {timeout} s') from None


def rclpy_missing() -> str | None:
    try:
        import rclpy  # noqa: F401
    except ImportError as e:
        return str(e)
    return None
