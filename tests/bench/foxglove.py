"""The Foxglove path beside the rosbridge path, on one sim gateway.

    .venv/bin/python -m tests.bench foxglove                  # about 2 minutes
    .venv/bin/python -m tests.bench foxglove --seconds 3 --repeats 1 --out foxglove.json

It starts ``python -m gateway --robot none --history none`` and measures, each point ``--repeats``
times (the median shown, with the min and max):

* ``rate``: std_msgs/msg/String of 64 and 1024 bytes, one publisher and one subscriber in this
  process with ``--window`` messages in flight, for ``--seconds``: messages a second delivered,
  the one-way latency p50/p95 and the gateway's CPU per message. The rosbridge path publishes
  and subscribes JSON ops; the Foxglove path publishes on a client channel in CDR and
  subscribes to the channel (CDR message data).
* ``camera``: a 640x480 rgb8 sensor_msgs/msg/Image published at 30 Hz (by a Foxglove client in
  CDR, the cheapest way in, the same for every point) to 0 subscribers (what taking it in costs),
  3 rosbridge JSON subscribers (uint8[] as base64), 3 rosbridge CBOR subscribers and 3 Foxglove
  subscribers (with the same subscription id, as the same layout opened in three apps, which
  share one frame; and with ids apart, one frame each): the frames a second the slowest one
  got, and the gateway's CPU.

``--backend rclpy`` runs the gateway on a Jazzy graph (in a loopback-only network namespace, as
``make bench ARGS="--backend rclpy"``); the camera is then a plain rclpy node (tests/bench/rosnodes.py)
and its points are 3 JSON, 3 CBOR, 3 cbor-raw and 3 Foxglove subscribers (both ways).

Every row has the machine's other load beside it (``other%``: what the rest of the machine used
meanwhile, 100 = one core; the 1-minute load average before the run is printed first).
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import struct
import sys
import time

import orjson
from websockets.asyncio.client import connect

from tests.bench.client import STAMP_LEN, StringFrames, percentile, read_stamp
from tests.bench.payloads import image
from tests.bench.report import save
from tests.bench.servers import ProcMeter, Window, default_rosgate_args, start_rosgate

FOXGLOVE = 'foxglove.websocket.v1'
STRING = 'std_msgs/msg/String'
CDR_HEADER = b'\x00\x01\x00\x00'
SIZES = (64, 1024)
CAMERA_RATE = 30.0
WARM = 10.0   # s at most for a path to deliver its first message


async def _open(url: str, foxglove: bool):
    return await connect(url, subprotocols=[FOXGLOVE] if foxglove else None, max_size=None, max_queue=64,
                         compression=None, ping_interval=None, proxy=None, open_timeout=20, close_timeout=2)


class FoxChannels:
    """The channels a Foxglove connection was told of (read from its JSON frames)."""

    def __init__(self):
        self.ids: dict[str, int] = {}
        self.seen = asyncio.Event()

    def take(self, frame) -> bool:
        """True for a JSON frame (taken here), False for message data."""
        if not isinstance(frame, str):
            return False
        msg = orjson.loads(frame)
        if msg.get('op') == 'advertise':
            self.ids.update((c['topic'], c['id']) for c in msg['channels'])
            self.seen.set()
        return True

    async def wait(self, ws, topic: str, timeout: float = WARM) -> int:
        """The channel id of ``topic``, reading ``ws`` until it is advertised."""
        deadline = time.monotonic() + timeout
        while topic not in self.ids:
            self.take(await asyncio.wait_for(ws.recv(), max(0.01, deadline - time.monotonic())))
        return self.ids[topic]


def string_cdr(text: bytes) -> bytes:
    """std_msgs/msg/String as CDR: the length with its NUL, the bytes, the NUL."""
    return CDR_HEADER + struct.pack('<I', len(text) + 1) + text + b'\x00'


async def _fox_publisher(url: str, topic: str, type_: str):
    ws = await _open(url, True)
    await ws.send(orjson.dumps({'op': 'advertise', 'channels': [
        {'id': 1, 'topic': topic, 'encoding': 'cdr', 'schemaName': type_}]}).decode())
    return ws, b'\x01' + struct.pack('<I', 1)


async def _fox_subscriber(url: str, topic: str, sid: int = 1):
    ws = await _open(url, True)
    channels = FoxChannels()
    channel = await channels.wait(ws, topic)
    await ws.send(orjson.dumps({'op': 'subscribe', 'subscriptions': [{'id': sid, 'channelId': channel}]}).decode())
    return ws, channels


async def rate(url: str, pid: int, path: str, size: int, window: int, seconds: float) -> dict:
    """Messages a second through one path, ``window`` in flight."""
    topic = f'/bench/{path}_{size}_{time.monotonic_ns()}'
    frames = StringFrames(topic, size)
    filler = b'x' * (size - STAMP_LEN)
    if path == 'foxglove':
        pub, prefix = await _fox_publisher(url, topic, STRING)
        sub, channels = await _fox_subscriber(url, topic)

        def make(seq: int) -> bytes:
            return prefix + string_cdr(b'%012d%020d' % (seq, time.monotonic_ns()) + filler)

        def stamp(frame) -> tuple[int, int] | None:
            if channels.take(frame) or frame[0] != 0x01:
                return None
            return int(frame[21:33]), int(frame[33:53])   # 13 header + 4 CDR + 4 length, then the text
    else:
        pub, sub = await _open(url, False), await _open(url, False)
        await pub.send(orjson.dumps({'op': 'advertise', 'topic': topic, 'type': STRING}).decode())
        await sub.send(orjson.dumps({'op': 'subscribe', 'topic': topic, 'type': STRING}).decode())
        make = frames.frame

        def stamp(frame) -> tuple[int, int] | None:
            return read_stamp(frame.encode() if isinstance(frame, str) else frame)

    credit = asyncio.Semaphore(window)
    state = {'from': None, 'count': 0, 'lat': [], 'first': asyncio.Event(), 'stop': None}

    async def read() -> None:
        async for frame in sub:
            got = stamp(frame)
            if got is None:
                continue
            credit.release()
            state['first'].set()
            now = time.monotonic_ns()
            if state['from'] is not None and got[0] >= state['from'] and (state['stop'] is None or now <= state['stop']):
                state['count'] += 1
                state['lat'].append(now - got[1])

    reader = asyncio.create_task(read())
    seq = 0
    try:
        text = path != 'foxglove'
        deadline = time.monotonic() + WARM
        while not state['first'].is_set():   # until the path delivers (a Foxglove channel is offered within a second)
            if time.monotonic() > deadline:
                raise TimeoutError(f'{path}: nothing delivered in {WARM:g} s')
            try:
                await asyncio.wait_for(credit.acquire(), 0.2)
            except asyncio.TimeoutError:
                credit = asyncio.Semaphore(window)   # what went out before the subscription is lost
                continue
            await pub.send(make(seq).decode() if text else make(seq))
            seq += 1
        state['from'] = seq
        first = seq
        meter = Window(ProcMeter(pid))
        stop_at = time.monotonic() + seconds
        while time.monotonic() < stop_at:
            await credit.acquire()
            await pub.send(make(seq).decode() if text else make(seq))
            seq += 1
        state['stop'] = time.monotonic_ns()
        elapsed = time.monotonic() - meter.t0
        figures = meter.stop()
    finally:
        reader.cancel()
        await pub.close()
        await sub.close()
    lat = sorted(state['lat'])
    return {'msg_per_s': state['count'] / elapsed, 'lat_p50_ms': _ms(percentile(lat, 50)),
            'lat_p95_ms': _ms(percentile(lat, 95)), 'delivered_pct': 100 * state['count'] / max(1, seq - first),
            'server_us_per_msg': 1e6 * figures['server_cpu_s'] / max(1, state['count']),
            'server_cpu_pct': figures['server_cpu_pct'], 'other_cpu_pct': figures['other_cpu_pct']}


def _ms(ns: float | None) -> float | None:
    return None if ns is None else ns / 1e6


async def camera(url: str, pid: int, kind: str, subscribers: int, seconds: float, rclpy: bool = False) -> dict:
    """A 640x480 rgb8 camera at 30 Hz to ``subscribers`` of one ``kind`` (json, cbor, cbor-raw,
    foxglove: the clients subscribe with the same id, as the same layout opened in each app does;
    foxglove-apart: with ids 1, 2, 3): on the sim a Foxglove client publishes it in CDR; on rclpy a
    camera node does."""
    topic = f'/bench/camera_{kind.replace("-", "_")}_{time.monotonic_ns()}'
    payload = image()
    node = pub = None
    if rclpy:
        from tests.bench.rosgraph import ImageNode
        node = ImageNode(topic, CAMERA_RATE)
    else:
        pub, prefix = await _fox_publisher(url, topic, payload.type)
        frame = prefix + payload.cdr()
    counts = [0] * subscribers
    first = [asyncio.Event() for _ in range(subscribers)]
    subs, readers = [], []

    async def publish(until: float) -> int:
        if node is not None:   # the node publishes by itself: what it sent meanwhile
            before = await node.count()
            await asyncio.sleep(max(0.0, until - time.monotonic()))
            return await node.count() - before
        sent, next_at = 0, time.monotonic()
        while next_at < until:
            await pub.send(frame)
            sent += 1
            next_at += 1 / CAMERA_RATE
            await asyncio.sleep(max(0.0, next_at - time.monotonic()))
        return sent

    async def read(i: int, ws, channels: FoxChannels | None) -> None:
        async for data in ws:
            if channels is not None and channels.take(data):
                continue
            if channels is None and isinstance(data, str) and '"publish"' not in data[:64]:
                continue
            counts[i] += 1
            first[i].set()

    try:
        warm = asyncio.create_task(publish(time.monotonic() + WARM))
        for i in range(subscribers):
            if kind.startswith('foxglove'):   # one id for all, as the same layout in each app; or ids apart
                ws, channels = await _fox_subscriber(url, topic, i + 1 if kind == 'foxglove-apart' else 1)
            else:
                ws, channels = await _open(url, False), None
                op = {'op': 'subscribe', 'topic': topic, 'type': payload.type}
                if kind != 'json':
                    op['compression'] = kind
                await ws.send(orjson.dumps(op).decode())
            subs.append(ws)
            readers.append(asyncio.create_task(read(i, ws, channels)))
        if subscribers:
            await asyncio.wait_for(asyncio.gather(*(f.wait() for f in first)), WARM)
        else:   # as long as the others warm up: a topic's first second costs more (its publisher, the hub's look)
            await asyncio.sleep(1.5)
        warm.cancel()
        start = list(counts)
        meter = Window(ProcMeter(pid))
        sent = await publish(time.monotonic() + seconds)
        await asyncio.sleep(0.2)   # the last frames on their way
        elapsed = time.monotonic() - meter.t0
        figures = meter.stop()
    finally:
        for r in readers:
            r.cancel()
        for ws in (*([pub] if pub is not None else []), *subs):
            await ws.close()
        if node is not None:
            node.stop()
    got = [c - s for c, s in zip(counts, start)]
    return {'published_hz': sent / seconds, 'slowest_hz': min(got) / seconds if got else None,
            'server_cpu_pct': figures['server_cpu_pct'],
            'server_ms_per_frame': 1e3 * figures['server_cpu_s'] / max(1, sent),
            'other_cpu_pct': figures['other_cpu_pct'], 'elapsed_s': elapsed}


def median_of(runs: list[dict]) -> dict:
    out = {}
    for key in runs[0]:
        values = [r[key] for r in runs if isinstance(r.get(key), (int, float))]
        if values:
            out[key] = {'median': statistics.median(values), 'min': min(values), 'max': max(values)}
    return out


def show(name: str, summary: dict, keys: list[str]) -> None:
    cells = []
    for key in keys:
        v = summary.get(key)
        cells.append(f'{key} {v["median"]:.4g} [{v["min"]:.4g}..{v["max"]:.4g}]' if v else f'{key} -')
    print(f'{name:32} ' + '  '.join(cells), flush=True)


async def run(args) -> dict:
    rclpy = args.backend == 'rclpy'
    if rclpy:
        from tests.bench.rosgraph import start_rosgate_rclpy
        target = start_rosgate_rclpy(['--backend', 'rclpy', '--history', 'none', *args.rosgate_arg])
    else:
        target = start_rosgate([*default_rosgate_args(), '--history', 'none', *args.rosgate_arg])
    results: dict = {'backend': args.backend, 'loadavg_before': os.getloadavg(), 'rate': {}, 'camera': {}}
    print(f'load average before: {results["loadavg_before"][0]:.2f} (1 min), {os.cpu_count()} cores', flush=True)
    try:
        if 'rate' in args.only:
            for path in ('rosbridge', 'foxglove'):   # not reported: each path's first use (conversions made per type)
                await rate(target.url, target.pid, path, SIZES[0], args.window, 1.0)
            for size in SIZES:
                for path in ('rosbridge', 'foxglove'):
                    runs = [await rate(target.url, target.pid, path, size, args.window, args.seconds)
                            for _ in range(args.repeats)]
                    summary = results['rate'][f'{path} {size} B'] = median_of(runs)
                    show(f'{path} {size} B W={args.window}', summary,
                         ['msg_per_s', 'lat_p50_ms', 'lat_p95_ms', 'server_us_per_msg', 'other_cpu_pct'])
        if 'camera' in args.only:
            points = ((('json', 3), ('cbor', 3), ('cbor-raw', 3), ('foxglove', 3), ('foxglove-apart', 3)) if rclpy else
                      (('foxglove', 0), ('json', 3), ('cbor', 3), ('foxglove', 3), ('foxglove-apart', 3)))
            # not reported: the gateway's first images fault in the memory for them (measured: the
            # first point took 3 ms a frame, the same point after it 0.9 ms)
            await camera(target.url, target.pid, 'cbor', 1, 2.0, rclpy)
            for kind, count in points:
                label = 'in only' if count == 0 else f'{count} {kind}'
                runs = [await camera(target.url, target.pid, kind, count, args.seconds, rclpy)
                        for _ in range(args.repeats)]
                summary = results['camera'][label] = median_of(runs)
                show(f'640x480 rgb8 30 Hz, {label}', summary,
                     ['published_hz', 'slowest_hz', 'server_cpu_pct', 'server_ms_per_frame', 'other_cpu_pct'])
    finally:
        target.stop()
    results['loadavg_after'] = os.getloadavg()
    print(f'load average after: {results["loadavg_after"][0]:.2f} (1 min)', flush=True)
    return results


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog='python -m tests.bench foxglove')
    ap.add_argument('--seconds', type=float, default=5.0, help='per point [%(default)s]')
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--window', type=int, default=32, help='messages in flight in the rate points [%(default)s]')
    ap.add_argument('--only', choices=['rate', 'camera'], action='append')
    ap.add_argument('--backend', choices=['sim', 'rclpy'], default='sim',
                    help='rclpy: the gateway on a Jazzy graph in a loopback-only namespace, the camera a node')
    ap.add_argument('--rosgate-arg', action='append', default=[])
    ap.add_argument('--out')
    args = ap.parse_args(argv)
    args.only = set(args.only or ['rate', 'camera'])
    if args.backend == 'rclpy':
        from tests.bench import rosgraph
        rosgraph.check_ros_env()
        if not rosgraph.isolated():
            rosgraph.reexec_isolated(['foxglove', *argv])
    save(args.out, asyncio.run(run(args)))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
