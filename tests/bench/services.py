"""Services: AddTwoInts round trips over one connection with C calls in flight."""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass

import orjson
from websockets.exceptions import ConnectionClosed

from .client import close_quietly, open_ws, percentile, send_op
from .servers import ProcMeter, Target, Window

SERVICE = "/add_two_ints"


@dataclass(frozen=True)
class Call:
    """A service call adding 2 and 3: its type, request and the field of the sum in the reply."""

    type: str
    args: bytes
    sum_field: str

    def frame(self, call_id: str) -> bytes:
        return (b'{"op":"call_service","id":"%s","service":"%s","type":"%s","args":%s}'
                % (call_id.encode(), SERVICE.encode(), self.type.encode(), self.args))


ADD_TWO_INTS = Call("example_interfaces/srv/AddTwoInts", b'{"a":2,"b":3}', "sum")
# the same call on the PyPI Jazzy wheels, which have no example_interfaces (tests/bench/rosnodes.py)
BASIC_TYPES = Call("test_msgs/srv/BasicTypes", b'{"int64_value":2,"int32_value":3}', "int64_value")


async def services(target: Target, concurrency: int, duration: float, kind: Call = ADD_TWO_INTS) -> dict:
    ws = await open_ws(target.url)
    pending: dict[str, asyncio.Future] = {}
    statuses: list[str] = []

    async def reader() -> None:
        try:
            while True:
                frame = await ws.recv(decode=False)
                now = time.monotonic_ns()
                try:
                    reply = orjson.loads(frame)
                except orjson.JSONDecodeError:
                    continue
                future = pending.pop(str(reply.get("id")), None)
                if future is not None and not future.done():
                    future.set_result((now, reply))
                elif reply.get("op") == "status" and len(statuses) < 20:
                    statuses.append(frame[:300].decode("utf-8", "replace"))
        except ConnectionClosed:
            pass

    loop = asyncio.get_running_loop()

    async def call(call_id: str) -> tuple[int, dict]:
        future = loop.create_future()
        pending[call_id] = future
        sent = time.monotonic_ns()
        await ws.send(kind.frame(call_id), text=True)
        done, reply = await future
        return done - sent, reply

    task = asyncio.create_task(reader())
    lat: list[int] = []
    failures = 0
    try:
        if target.kind == "ceiling":
            await send_op(ws, {"op": "ceiling_preload", "service": SERVICE, "values": {kind.sum_field: 5}})
        for n in range(5):  # warm-up, and check the answer once
            _ns, reply = await asyncio.wait_for(call(f"warm:{n}"), 10)
            if not (reply.get("result") is True and (reply.get("values") or {}).get(kind.sum_field) == 5):
                raise RuntimeError(f"unexpected reply to {SERVICE}: {orjson.dumps(reply)[:300]!r}")

        window = Window(ProcMeter(target.pid))
        end = time.monotonic() + duration

        async def caller(k: int) -> None:
            nonlocal failures
            n = 0
            while time.monotonic() < end:
                ns, reply = await call(f"call_service:{SERVICE}:{k}:{n}")
                n += 1
                if reply.get("result") is True:
                    lat.append(ns)
                else:
                    failures += 1

        callers = [asyncio.create_task(caller(k)) for k in range(concurrency)]
        _done, unfinished = await asyncio.wait(callers, timeout=duration + 10)
        for stuck in unfinished:
            stuck.cancel()
        figures = window.stop()
    finally:
        task.cancel()
        await close_quietly(ws)

    lat.sort()
    return {
        "calls_per_s": len(lat) / figures["elapsed_s"],
        "lat_p50_ms": None if not lat else percentile(lat, 50) / 1e6,
        "lat_p95_ms": None if not lat else percentile(lat, 95) / 1e6,
        "lat_p99_ms": None if not lat else percentile(lat, 99) / 1e6,
        "failed": failures + len(unfinished),
        "server_us_per_call": None if figures["server_cpu_s"] is None or not lat
        else figures["server_cpu_s"] / len(lat) * 1e6,
        "server_cpu_pct": figures["server_cpu_pct"],
        "client_cpu_pct": figures["client_cpu_pct"],
        "other_cpu_pct": figures["other_cpu_pct"],
        **({"statuses": statuses} if statuses else {}),
    }
