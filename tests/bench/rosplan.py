"""The scenarios of `--backend rclpy`, for rosgate, the Rust server and the rclpy ceiling.

Websocket servers get the same scenarios as on the sim backend, with the ROS end played by
plain rclpy nodes where one is needed: the service is served by a `rosnodes.py serve` node and
images come from a 30 Hz `rosnodes.py image` camera node. The rclpy ceiling (`kind == "rclpy"`)
runs the same traffic between plain rclpy nodes and reports the same figures; its CPU is that of
the process holding those nodes.
"""

from __future__ import annotations

import asyncio
import re

from .client import subscribe
from .fanout import fanout
from .flow import read_frames, settle, unique_topic
from .rosgraph import ImageNode
from .servers import ProcMeter, Target, Window
from .services import BASIC_TYPES, services
from .topics import WARM_TIMEOUT, connections, slow_consumer, throughput

IMAGE = "sensor_msgs/msg/Image"


class NotApplicable(Exception):
    """This server has no figure for this point (the rclpy ceiling of the slow consumer)."""


async def ceiling(target: Target, command: dict, budget: float = 120.0) -> tuple[dict, dict]:
    """One command to the ceiling process: its result and the CPU figures of its measured window.

    The process measures its own CPU over the window (setup and warm-up left out); what the
    rest of the machine did meanwhile is not known here, so `other%` stays empty."""
    reply = await target.node.ask_async(command, budget)
    if "error" in reply:
        raise RuntimeError(reply["error"])
    result = reply["result"]
    cpu = result.pop("cpu_s")
    figures = {"server_cpu_s": cpu, "server_cpu_pct": 100 * cpu / result["window_s"],
               "client_cpu_pct": None, "other_cpu_pct": None}
    return result, figures


async def ros_throughput(target: Target, size: int, window: int, duration: float) -> dict:
    if target.kind != "rclpy":
        return await throughput(target, size, window, duration)
    result, fig = await ceiling(target, {"cmd": "throughput", "size": size, "window": window,
                                         "duration": duration})
    messages = result.pop("messages")
    return {**result, **fig, "server_us_per_msg": fig["server_cpu_s"] / messages * 1e6 if messages else None}


async def ros_fanout(target: Target, subscribers: int, rate: float, size: int, duration: float,
                     repeats: int, procs: int, malloc_tune: bool) -> list[dict]:
    if target.kind != "rclpy":
        return await fanout(target, subscribers, rate, size, duration, repeats, procs, malloc_tune)
    runs = []
    for _ in range(repeats):
        result, fig = await ceiling(target, {"cmd": "fanout", "subscribers": subscribers, "rate": rate,
                                             "size": size, "duration": duration})
        messages = result.pop("messages")
        runs.append({**result, **fig, "server_cpu_s_per_1000":
                     fig["server_cpu_s"] / messages * 1000 if messages else None})
    return runs


async def ros_services(target: Target, concurrency: int, duration: float) -> dict:
    if target.kind != "rclpy":
        return await services(target, concurrency, duration, BASIC_TYPES)
    result, fig = await ceiling(target, {"cmd": "services", "concurrency": concurrency,
                                         "duration": duration})
    calls = result.pop("calls")
    return {**result, **fig, "server_us_per_call": fig["server_cpu_s"] / calls * 1e6 if calls else None}


async def ros_images(target: Target, compression: str, subscribers: int, rate: float,
                     duration: float) -> dict:
    """The camera node's images at `rate` Hz to `subscribers` clients of one encoding.

    `sub_hz` is the slowest client's arrival rate during the window; `delivered_pct` counts,
    by sequence number, the images published during the window that reached the clients by
    1 s after it (a server that falls behind queues or drops them)."""
    camera = await asyncio.to_thread(ImageNode, unique_topic("camera"), rate)
    try:
        if target.kind == "rclpy":
            result, fig = await ceiling(target, {"cmd": "images", "topic": camera.topic,
                                                 "subscribers": subscribers, "duration": duration})
            elapsed = result["window_s"]
            published_hz = result["published"] / elapsed
            arrived, received, sent = result["arrived"], result["received"], result["published"]
        else:
            arrived, received, sent, published_hz, fig = await _ws_images(
                target, camera, compression, subscribers, duration)
            elapsed = fig["elapsed_s"]
    finally:
        await asyncio.to_thread(camera.stop)
    return {
        "sub_hz": min(arrived) / elapsed,
        "published_hz": published_hz,
        "delivered_pct": 100 * sum(received) / (sent * subscribers) if sent else None,
        "server_ms_per_msg": fig["server_cpu_s"] / sent * 1e3 if sent and fig["server_cpu_s"] is not None
        else None,
        "server_cpu_pct": fig["server_cpu_pct"],
        "client_cpu_pct": fig["client_cpu_pct"],
        "other_cpu_pct": fig["other_cpu_pct"],
    }


async def _ws_images(target: Target, camera: ImageNode, compression: str, subscribers: int,
                     duration: float):
    seqs: list[list[int | None]] = [[] for _ in range(subscribers)]
    async with connections(target.url, subscribers) as subs:
        readers = []
        for i, sub in enumerate(subs):
            await subscribe(sub, camera.topic, IMAGE, compression)
            readers.append(asyncio.create_task(
                read_frames(sub, lambda f, _n, i=i: seqs[i].append(image_seq(f)))))
        try:
            if not await settle(lambda: all(seqs), WARM_TIMEOUT):
                raise TimeoutError("no image delivered during warm-up")
            await asyncio.sleep(0.2)  # what queued during discovery
            first, t_first = await camera.sample()
            base = [len(s) for s in seqs]
            window = Window(ProcMeter(target.pid))
            await asyncio.sleep(duration)
            figures = window.stop()
            arrived = [len(s) - b for s, b in zip(seqs, base)]
            end, t_end = await camera.sample()
            await settle(lambda: all(s[-1] is not None and s[-1] >= end - 1 for s in seqs), 1.0)
        finally:
            for reader in readers:
                reader.cancel()
    received = [sum(1 for n in s if n is not None and first <= n < end) for s in seqs]
    return arrived, received, end - first, (end - first) / (t_end - t_first), figures


JSON_SEC = re.compile(rb'"sec":\s*(\d+)')
CBOR_UINT = {0x18: 1, 0x19: 2, 0x1A: 4, 0x1B: 8}


def image_seq(frame: bytes) -> int | None:
    """header.stamp.sec of an image publish frame, JSON or CBOR, read from its first bytes."""
    head = frame[:300]
    if head[:1] == b"{":
        match = JSON_SEC.search(head)
        return int(match.group(1)) if match else None
    at = head.find(b"\x63sec")  # CBOR text "sec", then an unsigned integer
    if at < 0 or at + 4 >= len(head):
        return None
    first = head[at + 4]
    if first < 0x18:
        return first
    size = CBOR_UINT.get(first)
    return None if size is None else int.from_bytes(head[at + 5:at + 5 + size], "big")


async def ros_slow_consumer(target: Target, duration: float, rate: float = 30.0) -> dict:
    if target.kind == "rclpy":
        raise NotApplicable("plain rclpy nodes have no socket to stop reading")
    camera = await asyncio.to_thread(ImageNode, unique_topic("slow_camera"), rate)
    try:
        return await slow_consumer(target, duration, rate, camera=camera)
    finally:
        await asyncio.to_thread(camera.stop)


def plan(cfg):
    """(scenario, label, point, run(target), repeated?) as runner.plan, for --backend rclpy."""
    from .runner import shared_points

    ros = {"throughput": ros_throughput, "fanout": ros_fanout, "services": ros_services,
           "slow_consumer": ros_slow_consumer}
    for scenario in cfg.scenarios:
        yield from shared_points(cfg, scenario, ros)
        if scenario == "images":
            for enc in ("none", "cbor"):
                label = "json" if enc == "none" else enc
                yield (scenario, f"640x480 rgb8 30Hz 3x{label}",
                       {"subscribers": 3, "compression": enc, "rate": 30},
                       lambda t, e=enc: ros_images(t, e, 3, 30.0, cfg.rate_s), True)
