"""Rosbridge client pieces for the harness: connections, ops and cheap frame reading.

The client is the `websockets` asyncio implementation (C-accelerated masking);
`python -m tests.bench.clientcost` measures it against tornado's client.
Hot-path frames are pre-built bytes; received frames are read as bytes and only
the few fields the harness needs are located, never fully parsed.
"""

from __future__ import annotations

import time

import orjson
from websockets.asyncio.client import ClientConnection, connect

STAMP_LEN = 32  # 12 digits of sequence number, 20 digits of CLOCK_MONOTONIC ns


async def open_ws(url: str, max_queue: int = 64) -> ClientConnection:
    return await connect(
        url,
        max_size=None,
        max_queue=max_queue,
        compression=None,
        ping_interval=None,
        proxy=None,
        open_timeout=20,
        close_timeout=2,
    )


async def send_op(ws: ClientConnection, op: dict) -> None:
    await ws.send(orjson.dumps(op), text=True)


async def advertise(ws: ClientConnection, topic: str, type_: str) -> None:
    await send_op(ws, {"op": "advertise", "id": f"advertise:{topic}", "topic": topic, "type": type_})


async def subscribe(ws: ClientConnection, topic: str, type_: str, compression: str = "none") -> None:
    op = {"op": "subscribe", "id": f"subscribe:{topic}", "topic": topic, "type": type_}
    if compression != "none":
        op["compression"] = compression
    await send_op(ws, op)


async def close_quietly(*conns: ClientConnection) -> None:
    for ws in conns:
        try:
            await ws.close()
        except Exception:
            pass


def publish_prefix(topic: str) -> bytes:
    """Start of a std_msgs/msg/String publish frame, up to the opening quote of data."""
    return b'{"op":"publish","topic":"%s","msg":{"data":"' % topic.encode()


class StringFrames:
    """Publish frames of a String whose data is `size` ASCII bytes, stamped per message."""

    def __init__(self, topic: str, size: int) -> None:
        if size < STAMP_LEN:
            raise ValueError(f"payload must be at least {STAMP_LEN} bytes")
        self.prefix = publish_prefix(topic)
        self.suffix = b"x" * (size - STAMP_LEN) + b'"}}'

    def frame(self, seq: int) -> bytes:
        return b"".join((self.prefix, b"%012d%020d" % (seq, time.monotonic_ns()), self.suffix))


def is_publish(frame: bytes) -> bool:
    """A delivery: any binary (CBOR) frame, or a JSON frame whose op is publish."""
    if not frame or frame[0] != 0x7B:  # "{": JSON; anything else is CBOR
        return True
    return frame.find(b'"publish"', 0, 64) >= 0


def read_stamp(frame: bytes) -> tuple[int, int] | None:
    """(sequence, send time ns) of a String publish frame made by StringFrames."""
    at = frame.find(b'"data":')
    if at < 0:
        return None
    start = frame.find(b'"', at + 7) + 1
    try:
        return int(frame[start:start + 12]), int(frame[start + 12:start + STAMP_LEN])
    except ValueError:
        return None


def percentile(sorted_values: list[float], q: float) -> float | None:
    if not sorted_values:
        return None
    index = min(len(sorted_values) - 1, max(0, round(q / 100 * (len(sorted_values) - 1))))
    return sorted_values[index]
