"""A long lesson: pages on a ``--fleet`` gateway driving their turtles for minutes.

    .venv/bin/python -m tests.bench lesson                  # 30 pages, 10 minutes
    .venv/bin/python -m tests.bench lesson --minutes 2      # a quicker run
    make bench ARGS="lesson --minutes 3 --out lesson.json"

It starts ``python -m gateway --robot turtlesim --fleet N`` and opens N websocket pages. Each
page claims a station (``/fleet/claim``), subscribes to its turtle's pose (no throttle, as a
program's subscription does) and to its ``world/markers`` (as the IDE's world view does,
queue_length 20), publishes ``cmd_vel`` at 10 Hz (a meander that differs per page, so the
turtles cover their squares and meet the walls) and calls ``/rosapi/topics`` once a second (as
the IDE's graph refresh does); with ``--camera`` each station also has a rover and each page
shows its camera as the teleop page does (throttle 200 ms, queue_length 1). Every minute it
samples the gateway's RSS (``VmRSS``), the CPU it used over the minute, the rosapi latency
p50/p95 of the minute and what the pages received. At
the end a late viewer subscribes to the first station's ``world/markers``; the first message it
gets (the latched snapshot) is measured in bytes.

The bar (issue 23, item 9), checked at the end, exit status 1 when one is missed:
RSS growth from minute 1 to the last minute < 25 MB; CPU not climbing (the last minute's CPU
at most minute 1's x 1.25 + 5 points); rosapi p95 < 100 ms over the run and in the last
minute; the late viewer's snapshot < 1 MB.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import sys
import tempfile
import time
from dataclasses import dataclass, field

import orjson
from websockets.exceptions import ConnectionClosed

from .client import close_quietly, open_ws, percentile, send_op
from .servers import ProcMeter, Target, machine_busy_s, start_rosgate

RATE = 10.0                  # cmd_vel per second per page
CALL_PERIOD = 1.0            # seconds between rosapi calls of a page
CALL_TIMEOUT = 10.0
WARMUP = 10.0                # seconds of driving before minute 1 starts (default)
MB = 1e6

BAR_RSS_GROWTH_MB = 25.0
BAR_ROSAPI_P95_MS = 100.0
BAR_SNAPSHOT_BYTES = 1_000_000
CPU_SLACK = (1.25, 5.0)      # last minute's CPU <= minute 1's * 1.25 + 5 points


@dataclass
class Minute:
    """What one sampling period saw."""

    index: int
    latencies: list[float] = field(default_factory=list)   # rosapi round trips, ms
    failed_calls: int = 0
    poses: int = 0
    marker_msgs: int = 0
    marker_bytes: int = 0
    camera_frames: int = 0
    commands: int = 0
    rss_mb: float | None = None
    cpu_pct: float | None = None
    other_pct: float | None = None
    client_pct: float | None = None
    seconds: float = 0.0

    def figures(self) -> dict:
        lat = sorted(self.latencies)
        per_s = max(self.seconds, 1e-9)
        return {
            "minute": self.index, "rss_mb": self.rss_mb, "cpu_pct": self.cpu_pct,
            "rosapi_p50_ms": percentile(lat, 50), "rosapi_p95_ms": percentile(lat, 95),
            "rosapi_calls": len(lat), "rosapi_failed": self.failed_calls,
            "pose_per_s": self.poses / per_s, "markers_per_s": self.marker_msgs / per_s,
            "markers_kib_per_s": self.marker_bytes / per_s / 1024,
            "camera_per_s": self.camera_frames / per_s, "commands_per_s": self.commands / per_s,
            "client_cpu_pct": self.client_pct, "other_cpu_pct": self.other_pct,
        }


class Lesson:
    """The pages of a lesson; ``page_url(index)`` gives a page its address (default: ``url``; a
    signed-in page's carries its token)."""

    def __init__(self, url: str, stations: int, camera: bool = False, page_url=None) -> None:
        self.url, self.stations, self.camera = url, stations, camera
        self.page_url = page_url or (lambda index: url)
        self.minute = Minute(0)       # the bucket being filled; 0 is the warm-up
        self.stop = asyncio.Event()
        self.namespaces: list[str] = []
        self.errors: list[str] = []

    async def page(self, index: int, ready: asyncio.Queue) -> None:
        ws = await open_ws(self.page_url(index), max_queue=256)
        pending: dict[str, float] = {}
        claimed: asyncio.Future = asyncio.get_running_loop().create_future()

        async def reader() -> None:
            try:
                while True:
                    frame = await ws.recv(decode=False)
                    head = frame[:80]
                    if b'"publish"' in head:
                        if b'/pose"' in head:
                            self.minute.poses += 1
                        elif b'/camera/' in head:
                            self.minute.camera_frames += 1
                        else:
                            self.minute.marker_msgs += 1
                            self.minute.marker_bytes += len(frame)
                        continue
                    reply = orjson.loads(frame)
                    if reply.get("op") != "service_response":
                        if len(self.errors) < 20:
                            self.errors.append(frame[:300].decode("utf-8", "replace"))
                        continue
                    if reply.get("id") == "claim":
                        if not claimed.done():
                            claimed.set_result(reply)
                        continue
                    sent = pending.pop(str(reply.get("id")), None)
                    if sent is None:
                        continue
                    if reply.get("result"):
                        self.minute.latencies.append((time.monotonic() - sent) * 1000)
                    else:
                        self.minute.failed_calls += 1
            except ConnectionClosed:
                pass

        read = asyncio.create_task(reader())
        try:
            await send_op(ws, {"op": "call_service", "id": "claim", "service": "/fleet/claim",
                               "type": "std_srvs/srv/Trigger", "args": {}})
            reply = await asyncio.wait_for(claimed, 30)
            values = reply.get("values") or {}
            if not (reply.get("result") and values.get("success")):
                raise RuntimeError(f"page {index}: no station: {reply}")
            ns = values["message"]
            await send_op(ws, {"op": "subscribe", "id": "pose", "topic": f"{ns}/turtle1/pose",
                               "type": "turtlesim/msg/Pose"})
            await send_op(ws, {"op": "subscribe", "id": "world", "topic": f"{ns}/world/markers",
                               "type": "visualization_msgs/msg/MarkerArray", "queue_length": 20})
            if self.camera:   # as the teleop page shows a camera: 5 frames a second at most, newest only
                await send_op(ws, {"op": "subscribe", "id": "camera", "topic": f"{ns}/camera/image_raw/compressed",
                                   "type": "sensor_msgs/msg/CompressedImage", "throttle_rate": 200,
                                   "queue_length": 1})
            cmd = f"{ns}/turtle1/cmd_vel"
            await send_op(ws, {"op": "advertise", "id": "cmd", "topic": cmd, "type": "geometry_msgs/msg/Twist"})
            await ready.put(ns)
            loop = asyncio.get_running_loop()
            start = loop.time()
            phase = 0.7 * index
            tick = 0
            calls = 0
            next_call = start + (index % 10) / 10   # spread the pages' calls over the second
            while not self.stop.is_set():
                t = tick / RATE
                lin = 1.0 + 0.5 * math.sin(0.5 * t + phase)
                ang = 1.2 * math.sin(0.23 * t + phase) + 0.3 * math.cos(0.05 * t + phase)
                await ws.send(b'{"op":"publish","topic":"%s","msg":{"linear":{"x":%.4f,"y":0.0,"z":0.0},'
                              b'"angular":{"x":0.0,"y":0.0,"z":%.4f}}}' % (cmd.encode(), lin, ang), text=True)
                self.minute.commands += 1
                now = loop.time()
                if now >= next_call:
                    next_call += CALL_PERIOD
                    calls += 1
                    call_id = f"t{calls}"
                    for stale in [k for k, at in pending.items() if time.monotonic() - at > CALL_TIMEOUT]:
                        del pending[stale]
                        self.minute.failed_calls += 1
                    pending[call_id] = time.monotonic()
                    await send_op(ws, {"op": "call_service", "id": call_id, "service": "/rosapi/topics",
                                       "type": "rosapi_msgs/srv/Topics", "args": {}})
                tick += 1
                delay = start + tick / RATE - loop.time()
                if delay > 0:
                    try:
                        await asyncio.wait_for(self.stop.wait(), delay)
                    except asyncio.TimeoutError:
                        pass
        finally:
            read.cancel()
            await close_quietly(ws)


async def next_station(ready: asyncio.Queue, pages: list[asyncio.Task]) -> str:
    """The station the next page claimed (what it put on ``ready``); an error saying why when a page
    ended first (a page ends only by failing) or none came within a minute."""
    got = asyncio.create_task(ready.get())
    done, _ = await asyncio.wait({got, *pages}, timeout=60, return_when=asyncio.FIRST_COMPLETED)
    if got not in done:
        got.cancel()
        failed = [p for p in pages if p.done()]
        raise RuntimeError(f"pages did not start: {failed[0].exception() if failed else 'timeout'}")
    return got.result()


async def late_viewer(url: str, topic: str) -> dict:
    """The first message a new subscriber of ``topic`` receives: its size, wait and contents."""
    ws = await open_ws(url)
    try:
        started = time.monotonic()
        await send_op(ws, {"op": "subscribe", "id": "late", "topic": topic,
                           "type": "visualization_msgs/msg/MarkerArray", "queue_length": 20})
        while True:
            frame = await asyncio.wait_for(ws.recv(decode=False), 60)
            if b'"publish"' in frame[:80]:
                break
        waited = time.monotonic() - started
        markers = orjson.loads(frame)["msg"]["markers"]
        by_ns: dict[str, list[int]] = {}
        for m in markers:
            counts = by_ns.setdefault(m["ns"], [0, 0])
            counts[0] += 1
            counts[1] += len(m.get("points") or [])
        return {"topic": topic, "bytes": len(frame), "wait_ms": waited * 1000,
                "markers": {ns: {"markers": c[0], "points": c[1]} for ns, c in sorted(by_ns.items())}}
    finally:
        await close_quietly(ws)


async def drive(target: Target, stations: int, minutes: float, log, warmup: float = WARMUP,
                camera: bool = False) -> dict:
    lesson = Lesson(target.url, stations, camera)
    meter = ProcMeter(target.pid)
    ready: asyncio.Queue = asyncio.Queue()
    pages = [asyncio.create_task(lesson.page(i, ready)) for i in range(stations)]
    try:
        for _ in range(stations):
            lesson.namespaces.append(await next_station(ready, pages))
        log(f"{stations} pages driving; warm-up {warmup:g} s")
        await asyncio.sleep(warmup)
        rss0 = meter.rss_bytes()
        samples, latencies = [], []
        total = max(1, math.ceil(minutes))
        period = 60.0 * minutes / total
        for index in range(1, total + 1):
            lesson.minute = bucket = Minute(index)
            t0, cpu0, busy0, client0 = time.monotonic(), meter.sample(), machine_busy_s(), time.process_time()
            await asyncio.sleep(period)
            bucket.seconds = time.monotonic() - t0
            cpu = ProcMeter.cpu_between(cpu0, meter.sample())
            client = time.process_time() - client0
            rss = meter.rss_bytes()
            bucket.rss_mb = None if rss is None else rss / MB
            bucket.cpu_pct = None if cpu is None else 100 * cpu / bucket.seconds
            bucket.client_pct = 100 * client / bucket.seconds
            bucket.other_pct = max(0.0, 100 * (machine_busy_s() - busy0 - client - (cpu or 0)) / bucket.seconds)
            fig = bucket.figures()
            samples.append(fig)
            latencies += bucket.latencies
            log(f"  minute {index:2d}: RSS {fmt(fig['rss_mb'])} MB, CPU {fmt(fig['cpu_pct'])} %, "
                f"rosapi p50 {fmt(fig['rosapi_p50_ms'])} ms p95 {fmt(fig['rosapi_p95_ms'])} ms "
                f"({fig['rosapi_calls']} calls, {fig['rosapi_failed']} failed), "
                f"pose {fig['pose_per_s']:.0f}/s, markers {fig['markers_per_s']:.0f}/s "
                f"{fig['markers_kib_per_s']:.0f} KiB/s, camera {fig['camera_per_s']:.0f}/s, client CPU {fig['client_cpu_pct']:.0f} %, "
                f"other {fig['other_cpu_pct']:.0f} %")
        lesson.stop.set()
        await asyncio.gather(*pages, return_exceptions=True)
        late = await late_viewer(target.url, f"{lesson.namespaces[0]}/world/markers")
        return {"rss_start_mb": None if rss0 is None else rss0 / MB, "minutes": samples, "late_viewer": late,
                "errors": lesson.errors, "namespaces": lesson.namespaces, "latencies_ms": latencies}
    finally:
        lesson.stop.set()
        for p in pages:
            p.cancel()
        await asyncio.gather(*pages, return_exceptions=True)


def fmt(v, digits: int = 1) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def verdict(result: dict) -> list[tuple[str, str, bool]]:
    """(what, figure, met) for each item of the bar."""
    minutes = result["minutes"]
    first, last = minutes[0], minutes[-1]
    rows = []
    if first["rss_mb"] is not None:
        growth = last["rss_mb"] - first["rss_mb"]
        rows.append((f"RSS growth minute 1 -> {last['minute']} < {BAR_RSS_GROWTH_MB:g} MB",
                     f"{first['rss_mb']:.1f} -> {last['rss_mb']:.1f} MB ({growth:+.1f})", growth < BAR_RSS_GROWTH_MB))
    if first["cpu_pct"] is not None:
        limit = first["cpu_pct"] * CPU_SLACK[0] + CPU_SLACK[1]
        rows.append(("CPU not climbing (last minute <= minute 1 x 1.25 + 5)",
                     f"{first['cpu_pct']:.1f} -> {last['cpu_pct']:.1f} % (limit {limit:.1f})",
                     last["cpu_pct"] <= limit))
    p95 = percentile(sorted(result["latencies_ms"]), 95)
    rows.append((f"rosapi p95 < {BAR_ROSAPI_P95_MS:g} ms (run)", f"{fmt(p95)} ms",
                 p95 is not None and p95 < BAR_ROSAPI_P95_MS))
    rows.append((f"rosapi p95 < {BAR_ROSAPI_P95_MS:g} ms (last minute)", f"{fmt(last['rosapi_p95_ms'])} ms",
                 last["rosapi_p95_ms"] is not None and last["rosapi_p95_ms"] < BAR_ROSAPI_P95_MS))
    size = result["late_viewer"]["bytes"]
    rows.append((f"late viewer's snapshot < {BAR_SNAPSHOT_BYTES / MB:g} MB", f"{size / MB:.3f} MB ({size} bytes)",
                 size < BAR_SNAPSHOT_BYTES))
    return rows


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m tests.bench lesson", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--minutes", type=float, default=10.0, help="sampling minutes after the warm-up (default 10)")
    p.add_argument("--stations", type=int, default=30, help="pages and fleet stations (default 30)")
    p.add_argument("--warmup", type=float, default=WARMUP,
                   help=f"seconds of driving before minute 1 (default {WARMUP:g})")
    p.add_argument("--rosgate-arg", action="append", default=[],
                   help="an extra argument for the gateway's command line, repeatable")
    p.add_argument("--camera", action="store_true",
                   help="a rover beside each turtle (--robot rover) and each page showing its camera as the "
                        "teleop page does (throttle 200 ms, queue 1)")
    p.add_argument("--out", help="write the figures as JSON to this file")
    return p.parse_args(argv)


def log(text: str) -> None:
    print(text, flush=True)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if not args.minutes > 0 or args.stations < 1:
        raise SystemExit("--minutes must be positive and --stations at least 1")
    robots = ["--robot", "turtlesim", *(["--robot", "rover"] if args.camera else [])]
    gw_args = ["--backend", "sim", *robots, "--fleet", str(args.stations),
               "--programs-dir", tempfile.mkdtemp(prefix="bench-lesson-programs-"), *args.rosgate_arg]
    target = start_rosgate(gw_args)
    log(f"rosgate: {target.url} pid {target.pid} ({' '.join(target.argv)}); log {target.log}")
    try:
        result = asyncio.run(drive(target, args.stations, args.minutes, log, args.warmup, args.camera))
    finally:
        target.stop()
    rows = verdict(result)
    late = result["late_viewer"]
    log(f"\nlate viewer of {late['topic']}: {late['bytes']} bytes after {late['wait_ms']:.0f} ms; "
        + ", ".join(f"{ns} {c['markers']} markers {c['points']} points" for ns, c in late["markers"].items()))
    if result["errors"]:
        log(f"unexpected frames: {result['errors'][:3]}")
    log("\nthe bar:")
    for what, figure, met in rows:
        log(f"  {'ok  ' if met else 'MISS'} {what}: {figure}")
    if args.out:
        doc = {"argv": ["--minutes", str(args.minutes), "--stations", str(args.stations),
                        "--warmup", str(args.warmup), *(["--camera"] if args.camera else [])],
               "gateway": target.argv, **{k: v for k, v in result.items() if k != "latencies_ms"},
               "bar": [{"what": w, "figure": f, "met": m} for w, f, m in rows]}
        with open(args.out, "w") as f:
            json.dump(doc, f, indent=1)
        log(f"wrote {args.out}")
    return 0 if all(met for _, _, met in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
