"""Topic scenarios: throughput and latency, encodings, slow consumer."""

from __future__ import annotations

import asyncio
import base64
import contextlib
import time

from . import payloads
from .client import (
    StringFrames,
    advertise,
    close_quietly,
    open_ws,
    percentile,
    read_stamp,
    send_op,
    subscribe,
)
from .flow import SendWindow, publish_at, read_frames, settle, unique_topic
from .servers import ProcMeter, Target, Window

STRING = "std_msgs/msg/String"
WARM_TIMEOUT = 20.0


@contextlib.asynccontextmanager
async def connections(url: str, count: int, max_queue: int = 64):
    conns = []
    try:
        for _ in range(count):
            conns.append(await open_ws(url, max_queue=max_queue))
        yield conns
    finally:
        await close_quietly(*conns)


async def preload_frames(target: Target, ws, payload: payloads.Payload, topic: str,
                         compressions) -> None:
    if target.kind != "ceiling":
        return
    for compression in compressions:
        if compression == "none":
            continue
        frame = base64.b64encode(payload.server_frame(topic, compression)).decode()
        await send_op(ws, {"op": "ceiling_preload", "topic": topic,
                           "compression": compression, "frame": frame})


async def throughput(target: Target, size: int, window: int, duration: float) -> dict:
    """One publisher and one subscriber in this process; W messages in flight."""
    topic = unique_topic("tp")
    frames = StringFrames(topic, size)
    state = {"measure_from": None, "count": 0, "lat": [], "any": 0, "stop_at": None}
    statuses: list[str] = []

    async with connections(target.url, 2) as (pub, sub):
        await advertise(pub, topic, STRING)
        await subscribe(sub, topic, STRING)
        credit = SendWindow(window)

        def on_frame(frame: bytes, now: int) -> None:
            credit.release()
            state["any"] += 1
            stamp = read_stamp(frame)
            first = state["measure_from"]
            if stamp is None or first is None or stamp[0] < first:
                return
            state["lat"].append(now - stamp[1])
            stop_at = state["stop_at"]
            if stop_at is None or now <= stop_at:
                state["count"] += 1

        reader = asyncio.create_task(read_frames(sub, on_frame, statuses))
        try:
            seq = await _warm_up(pub, frames.frame, lambda: state["any"] > 0, credit)
            meter = Window(ProcMeter(target.pid))
            state["measure_from"] = seq
            first = seq

            def stopped() -> None:
                state["stop_at"] = time.monotonic_ns()
            seq, elapsed, figures = await _measure(pub, credit, meter, frames.frame, seq, duration, stopped)
        finally:
            credit.close()
            reader.cancel()

    lat = sorted(state["lat"])
    sent = seq - first
    return {
        "msg_per_s": state["count"] / elapsed,
        "mib_per_s": state["count"] * size / elapsed / 2**20,
        "lat_p50_ms": _ms(percentile(lat, 50)),
        "lat_p95_ms": _ms(percentile(lat, 95)),
        "lat_p99_ms": _ms(percentile(lat, 99)),
        "delivered_pct": 100 * len(lat) / sent if sent else None,
        "server_us_per_msg": _per(figures["server_cpu_s"], len(lat), 1e6),
        "server_cpu_pct": figures["server_cpu_pct"],
        "client_cpu_pct": figures["client_cpu_pct"],
        "other_cpu_pct": figures["other_cpu_pct"],
        **({"statuses": statuses} if statuses else {}),
    }


async def _measure(pub, credit, meter, frame_of, seq: int, duration: float, stopped=lambda: None):
    """Send frame_of(seq), frame_of(seq + 1) ... for ``duration`` s, each once the window has
    credit; ``stopped()`` when the last is sent, then wait for the window to drain. Returns (the
    next seq, the seconds measured, the meter's figures)."""
    end = time.monotonic() + duration
    while time.monotonic() < end:
        await credit.acquire()
        await pub.send(frame_of(seq), text=True)
        seq += 1
    stopped()
    elapsed = time.monotonic() - meter.t0
    await credit.drain()
    return seq, elapsed, meter.stop()


async def _warm_up(pub, make_frame, ready, credit: SendWindow | None = None) -> int:
    """Publish every 20 ms until `ready()`; then let in-flight messages arrive."""
    seq = 0
    deadline = time.monotonic() + WARM_TIMEOUT
    while not ready():
        if time.monotonic() > deadline:
            raise TimeoutError("no message delivered during warm-up")
        await pub.send(make_frame(seq), text=True)
        seq += 1
        await asyncio.sleep(0.02)
    await asyncio.sleep(0.05)
    if credit is not None:
        credit.inflight = 0
    return seq


async def encoding_max(target: Target, payload: payloads.Payload, compression: str,
                       window: int, duration: float) -> dict:
    """Max sustained rate of one payload to one subscriber of one encoding."""
    topic = unique_topic("enc")
    frame = payload.publish_frame(topic)
    state = {"count": 0, "bytes": 0, "any": 0, "measuring": False}
    statuses: list[str] = []

    async with connections(target.url, 2) as (pub, sub):
        await preload_frames(target, pub, payload, topic, [compression])
        await advertise(pub, topic, payload.type)
        await subscribe(sub, topic, payload.type, compression)
        credit = SendWindow(window)

        def on_frame(data: bytes, now: int) -> None:
            credit.release()
            state["any"] += 1
            if state["measuring"]:
                state["count"] += 1
                state["bytes"] += len(data)

        reader = asyncio.create_task(read_frames(sub, on_frame, statuses))
        try:
            await _warm_up(pub, lambda _seq: frame, lambda: state["any"] > 0, credit)
            meter = Window(ProcMeter(target.pid))
            state["measuring"] = True
            sent, elapsed, figures = await _measure(pub, credit, meter, lambda _seq: frame, 0, duration)
        finally:
            credit.close()
            reader.cancel()

    count = state["count"]
    return {
        "hz": count / elapsed,
        "wire_kib": state["bytes"] / count / 1024 if count else None,
        "publish_kib": len(frame) / 1024,
        "server_ms_per_msg": _per(figures["server_cpu_s"], count, 1e3),
        "delivered_pct": 100 * count / sent if sent else None,
        "server_cpu_pct": figures["server_cpu_pct"],
        "client_cpu_pct": figures["client_cpu_pct"],
        "other_cpu_pct": figures["other_cpu_pct"],
        **({"statuses": statuses} if statuses else {}),
    }


async def encoding_rate(target: Target, payload: payloads.Payload, compression: str,
                        subscribers: int, rate: float, duration: float) -> dict:
    """A payload at a fixed rate to N subscribers of one encoding (N=0: ingest only)."""
    topic = unique_topic("rate")
    frame = payload.publish_frame(topic)
    counts = [0] * subscribers

    async with connections(target.url, 1 + subscribers) as conns:
        pub, subs = conns[0], conns[1:]
        await preload_frames(target, pub, payload, topic, [compression])
        await advertise(pub, topic, payload.type)
        readers = []
        for i, sub in enumerate(subs):
            await subscribe(sub, topic, payload.type, compression)
            readers.append(asyncio.create_task(
                read_frames(sub, lambda _f, _n, i=i: counts.__setitem__(i, counts[i] + 1))))
        try:
            if subscribers:
                await _warm_up(pub, lambda _s: frame, lambda: all(counts))
            else:  # nothing to wait for: let the advertisement land
                await pub.send(frame, text=True)
                await asyncio.sleep(0.1)
            base = list(counts)
            meter = Window(ProcMeter(target.pid))
            sent = await publish_at(pub, lambda _s: frame, rate, time.monotonic() + duration, 0)
            expected = sent * subscribers
            await settle(lambda: sum(counts) - sum(base) >= expected, 1.0)
            figures = meter.stop()
        finally:
            for reader in readers:
                reader.cancel()

    delivered = sum(counts) - sum(base)
    return {
        "published_hz": sent / figures["elapsed_s"],
        "delivered_pct": 100 * delivered / expected if subscribers and expected else None,
        "server_ms_per_msg": _per(figures["server_cpu_s"], sent, 1e3),
        "server_cores": None if figures["server_cpu_pct"] is None else figures["server_cpu_pct"] / 100,
        "server_cpu_pct": figures["server_cpu_pct"],
        "client_cpu_pct": figures["client_cpu_pct"],
        "other_cpu_pct": figures["other_cpu_pct"],
    }


async def slow_consumer(target: Target, duration: float, rate: float = 30.0, healthy: int = 2,
                        camera=None) -> dict:
    """healthy+1 cbor image subscribers; one stops reading its socket part way through.

    The image comes from a websocket publisher here, or from `camera` (a ROS node publishing
    on `camera.topic` at `rate`, whose `count()` says how many it has sent)."""
    payload = payloads.image()
    topic = camera.topic if camera is not None else unique_topic("slow")
    frame = payload.publish_frame(topic)
    meter = ProcMeter(target.pid)
    arrivals: list[list[float]] = [[] for _ in range(healthy + 1)]
    rss: list[tuple[float, int]] = []

    async def sample_rss(t0: float) -> None:
        while True:
            value = meter.rss_bytes()
            if value is not None:
                rss.append((time.monotonic() - t0, value))
            await asyncio.sleep(0.5)

    async def camera_sent(until: float, before: int) -> int:
        await asyncio.sleep(until - time.monotonic())
        return await camera.count() - before

    async with connections(target.url, healthy + 2, max_queue=4) as conns:
        pub, subs = conns[0], conns[1:]
        if camera is None:
            await preload_frames(target, pub, payload, topic, ["cbor"])
            await advertise(pub, topic, payload.type)
        readers = []
        for i, sub in enumerate(subs):
            await subscribe(sub, topic, payload.type, "cbor")
            readers.append(asyncio.create_task(
                read_frames(sub, lambda _f, now, i=i: arrivals[i].append(now / 1e9))))
        slow = subs[-1]
        sampler = None
        try:
            if camera is None:
                await _warm_up(pub, lambda _s: frame, lambda: all(arrivals))
            elif not await settle(lambda: all(arrivals), WARM_TIMEOUT):
                raise TimeoutError("no image delivered during warm-up")
            window = Window(meter)
            t0 = time.monotonic()
            sampler = asyncio.create_task(sample_rss(t0))
            stall_at = t0 + min(10.0, duration / 6)
            end = t0 + duration
            if camera is None:
                publisher = asyncio.create_task(publish_at(pub, lambda _s: frame, rate, end, 0))
            else:
                publisher = asyncio.create_task(camera_sent(end, await camera.count()))
            await asyncio.sleep(stall_at - time.monotonic())
            readers[-1].cancel()
            slow.transport.pause_reading()
            rss_at_stall = meter.rss_bytes()
            sent = await publisher
            figures = window.stop()
        finally:
            if sampler is not None:
                sampler.cancel()
            for reader in readers:
                reader.cancel()
            slow.transport.abort()

    def rate_between(times: list[float], a: float, b: float) -> float:
        return sum(1 for t in times if a <= t < b) / (b - a)

    before = [rate_between(arrivals[i], t0, stall_at) for i in range(healthy)]
    settled = stall_at + min(1.0, (end - stall_at) / 4)  # frames in flight at the stall
    after = [rate_between(arrivals[i], settled, end) for i in range(healthy)]
    healthy_before = sum(before) / healthy
    healthy_after = sum(after) / healthy
    published_hz = sent / (end - t0)
    stall_rss = [value for t, value in rss if t0 + t >= stall_at]
    return {
        "published_hz": published_hz,
        "healthy_hz_before": healthy_before,
        "healthy_hz_stalled": healthy_after,
        "healthy_loss_pct": 100 * (1 - healthy_after / healthy_before) if healthy_before else None,
        "healthy_delivered_pct": 100 * healthy_after / published_hz if published_hz else None,
        "slow_received": len(arrivals[-1]),
        "rss_at_stall_mb": _mb(rss_at_stall),
        "rss_max_mb": _mb(max(stall_rss)) if stall_rss else None,
        "rss_growth_mb": _mb(max(stall_rss) - rss_at_stall) if stall_rss and rss_at_stall else None,
        "rss_end_mb": _mb(rss[-1][1]) if rss else None,
        "server_cpu_pct": figures["server_cpu_pct"],
        "client_cpu_pct": figures["client_cpu_pct"],
        "other_cpu_pct": figures["other_cpu_pct"],
        "rss_series_mb": [[round(t, 1), round(v / 2**20, 1)] for t, v in rss],
    }


def _ms(ns: float | None) -> float | None:
    return None if ns is None else ns / 1e6


def _mb(value: int | None) -> float | None:
    return None if value is None else value / 2**20


def _per(cpu_s: float | None, count: int, scale: float) -> float | None:
    return None if cpu_s is None or not count else cpu_s / count * scale
