"""Cameras for slow clients: how old frames are when they arrive, and what viewers cost.

    .venv/bin/python -m tests.bench camera                        # about 2 minutes
    .venv/bin/python -m tests.bench camera --seconds 30 --out camera.json
    .venv/bin/python -m tests.bench camera --gateway-dir /tmp/old --only websocket   # another checkout

It starts ``python -m gateway --robot none`` (from ``--gateway-dir``, default this checkout) and
publishes, through roslibpy, a 640x480 JPEG CompressedImage (~40 KiB) at 10 Hz stamped with the
wall clock. Then, one at a time, each for ``--seconds``:

* ``ws-default`` / ``ws-teleop``: a websocket client reading at ``--rate`` bits/s (default
  1 Mbit/s: it takes at most rate x elapsed bytes from its socket, whose SO_RCVBUF is 64 KiB)
  subscribed with no options / with the teleop page's (throttle_rate 200, queue_length 1);
* ``ws-image``: the same client with the teleop page's options now (throttle_rate 150,
  queue_length 1, ``"image": {"width": 320, "quality": 60}``: the subscribe extension);
* ``stream-slow`` / ``stream-slow-full``: a ``/stream`` viewer reading at the same rate, of
  mjpeg at 320x240 quality 50 / of the full frames (``type=ros_compressed``);
* ``viewers-1`` / ``viewers-12``: 1 and 12 fast ``/stream`` viewers of the 640x480 image at
  quality 80 (re-encoded): the gateway's CPU over the run.

For each client: frames per second received, the age of each frame (arrival time minus its
header stamp) p50 / p95 / max, and the p95 of the first and last thirds (growing or not).
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import re
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

from tests.bench.report import save
from tests.support.rawsocket import server_frame

REPO = Path(__file__).resolve().parents[2]
LINE = re.compile(r'websocket ws://([^:/]+):(\d+)')
BURST = 8192   # bytes a paced reader may take at once after being idle


def percentile(values: list[float], p: float) -> float | None:
    if not values:
        return None
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(p / 100 * (len(ordered) - 1))))]


class Gateway:
    def __init__(self, directory: Path, args: list[str]):
        env = {**os.environ, 'PYTHONPATH': str(directory)}
        self.proc = subprocess.Popen([sys.executable, '-m', 'gateway', '--port', '0', '--address', '127.0.0.1', *args],
                                     cwd=directory, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)
        line = self.proc.stdout.readline()
        m = LINE.search(line)
        if not m:
            self.proc.kill()
            raise RuntimeError(f'gateway did not start: {line!r}')
        self.port = int(m.group(2))

    def cpu_seconds(self) -> float:
        with open(f'/proc/{self.proc.pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')

    def stop(self) -> None:
        self.proc.terminate()
        self.proc.wait(10)


class Camera(threading.Thread):
    def __init__(self, port: int, topic: str):
        super().__init__(daemon=True)
        import roslibpy
        from tests.support.camera import frames
        self.roslibpy = roslibpy
        self.ros = roslibpy.Ros('127.0.0.1', port)
        self.ros.run(timeout=10)
        self.topic = roslibpy.Topic(self.ros, topic, 'sensor_msgs/msg/CompressedImage')
        self.topic.advertise()
        self.images = [base64.b64encode(f).decode() for f in frames()]
        self.size = sum(len(f) for f in frames()) // len(self.images)
        self.halt = threading.Event()

    def run(self) -> None:
        n, next_at = 0, time.monotonic()
        while not self.halt.is_set():
            sec, nanosec = divmod(time.time_ns(), 10**9)
            self.topic.publish(self.roslibpy.Message({'header': {'stamp': {'sec': sec, 'nanosec': nanosec},
                                                                 'frame_id': 'cam'},
                                                      'format': 'jpeg', 'data': self.images[n % len(self.images)]}))
            n += 1
            next_at += 0.1
            self.halt.wait(max(0.0, next_at - time.monotonic()))

    def stop(self) -> None:
        self.halt.set()
        self.join(5)
        self.ros.close()


class Paced:
    """A socket read no faster than ``rate`` bits/s (None: as fast as it comes)."""

    def __init__(self, port: int, request: bytes, rate: float | None, rcvbuf: int = 65536):
        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.settimeout(10)
        self.sock.connect(('127.0.0.1', port))
        self.sock.sendall(request)
        self.rate = rate / 8 if rate else None
        self.buf = bytearray()
        self.credit, self.at = 0.0, time.monotonic()

    def fill(self) -> None:
        """A token bucket of BURST bytes: a reader idle between frames does not save up credit
        to read the next frame faster than the rate (as a link would not)."""
        want = 65536
        if self.rate:
            now = time.monotonic()
            self.credit = min(BURST, self.credit + (now - self.at) * self.rate)
            self.at = now
            if self.credit < 1024:
                time.sleep((1024 - self.credit) / self.rate)
                self.credit, self.at = 1024, time.monotonic()
            want = int(min(want, self.credit))
        chunk = self.sock.recv(want)
        if not chunk:
            raise EOFError
        if self.rate:
            self.credit -= len(chunk)
        self.buf += chunk

    def take(self, n: int) -> bytes:
        while len(self.buf) < n:
            self.fill()
        out = bytes(self.buf[:n])
        del self.buf[:n]
        return out

    def until(self, marker: bytes) -> bytes:
        while marker not in self.buf:
            self.fill()
        i = self.buf.index(marker) + len(marker)
        return self.take(i)


def ws_client(port: int, rate: float | None, subscribe: dict) -> Paced:
    key = base64.b64encode(os.urandom(16)).decode()
    c = Paced(port, (f'GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n'
                     f'Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n').encode(), rate)
    c.until(b'\r\n\r\n')
    payload = json.dumps(subscribe).encode()
    mask = os.urandom(4)
    header = bytes([0x81]) + (bytes([0x80 | len(payload)]) if len(payload) < 126
                              else bytes([0x80 | 126]) + struct.pack('!H', len(payload)))
    c.sock.sendall(header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))
    return c


def ws_stamps(c: Paced):
    """Header stamps of the publish ops the client reads (seconds)."""
    while True:
        opcode, data = server_frame(c.take)
        if opcode not in (1, 2):
            continue
        op = json.loads(data)
        if op.get('op') == 'publish':
            stamp = op['msg']['header']['stamp']
            yield stamp['sec'] + stamp['nanosec'] / 1e9


def stream_client(port: int, rate: float | None, query: str) -> Paced:
    c = Paced(port, f'GET /stream?{query} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n'.encode(), rate)
    c.until(b'\r\n\r\n')
    c.until(b'--boundarydonotcross\r\n')
    return c


def stream_stamps(c: Paced):
    while True:
        head = c.until(b'\r\n\r\n').decode()
        fields = dict(line.split(': ', 1) for line in head.split('\r\n') if ': ' in line)
        c.take(int(fields['Content-Length']))
        c.until(b'--boundarydonotcross\r\n')
        yield float(fields['X-Timestamp'])


def measure(stamps, seconds: float) -> dict:
    ages, arrivals = [], []
    end = time.monotonic() + seconds
    for stamp in stamps:
        now = time.time()
        ages.append(now - stamp)
        arrivals.append(now)
        if time.monotonic() > end:
            break
    third = max(1, len(ages) // 3)
    span = arrivals[-1] - arrivals[0] if len(arrivals) > 1 else 0
    return {'frames': len(ages), 'fps': round((len(ages) - 1) / span, 2) if span else 0,
            'age_p50': _r(percentile(ages, 50)), 'age_p95': _r(percentile(ages, 95)), 'age_max': _r(max(ages)),
            'p95_first_third': _r(percentile(ages[:third], 95)), 'p95_last_third': _r(percentile(ages[-third:], 95))}


def _r(v: float | None) -> float | None:
    return None if v is None else round(v, 3)


def viewers_cpu(gw: Gateway, count: int, seconds: float) -> dict:
    clients = [stream_client(gw.port, None, 'topic=/cam/image_raw&quality=80') for _ in range(count)]
    halt = threading.Event()
    counts = [0] * count

    def read(i: int) -> None:
        try:
            for _ in stream_stamps(clients[i]):
                counts[i] += 1
                if halt.is_set():
                    return
        except (OSError, EOFError):
            pass

    threads = [threading.Thread(target=read, args=(i,), daemon=True) for i in range(count)]
    for t in threads:
        t.start()
    time.sleep(2)   # warm up
    cpu0, t0, frames0 = gw.cpu_seconds(), time.monotonic(), sum(counts)
    time.sleep(seconds)
    cpu1, t1, frames1 = gw.cpu_seconds(), time.monotonic(), sum(counts)
    halt.set()
    for c in clients:
        c.sock.close()
    return {'viewers': count, 'gateway_cpu_percent': round(100 * (cpu1 - cpu0) / (t1 - t0), 1),
            'frames_per_viewer_per_s': round((frames1 - frames0) / count / (t1 - t0), 2)}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog='python -m tests.bench camera')
    ap.add_argument('--seconds', type=float, default=20.0)
    ap.add_argument('--rate', type=float, default=1e6, help='bits/s a slow client reads (default 1 Mbit/s)')
    ap.add_argument('--gateway-dir', type=Path, default=REPO)
    ap.add_argument('--only', choices=['websocket', 'stream', 'viewers'], action='append')
    ap.add_argument('--out')
    args = ap.parse_args(argv)
    only = set(args.only or ['websocket', 'stream', 'viewers'])
    gw = Gateway(args.gateway_dir, ['--robot', 'none'])
    cam = Camera(gw.port, '/cam/image_raw/compressed')
    cam.start()
    results: dict = {'gateway_dir': str(args.gateway_dir), 'rate_bits': args.rate, 'frame_bytes': cam.size}
    try:
        time.sleep(1)
        sub = {'op': 'subscribe', 'topic': '/cam/image_raw/compressed', 'type': 'sensor_msgs/msg/CompressedImage'}
        runs = []
        if 'websocket' in only:
            runs += [('ws-default', lambda: ws_stamps(ws_client(gw.port, args.rate, sub))),
                     ('ws-teleop', lambda: ws_stamps(ws_client(gw.port, args.rate, {**sub, 'throttle_rate': 200,
                                                                                     'queue_length': 1})))]
            runs.append(('ws-image', lambda: ws_stamps(ws_client(gw.port, args.rate, {   # the teleop page's now
                **sub, 'throttle_rate': 150, 'queue_length': 1, 'image': {'width': 320, 'quality': 60}}))))
        if 'stream' in only:
            runs.append(('stream-slow', lambda: stream_stamps(
                stream_client(gw.port, args.rate, 'topic=/cam/image_raw&width=320&height=240&quality=50'))))
            runs.append(('stream-slow-full', lambda: stream_stamps(
                stream_client(gw.port, args.rate, 'topic=/cam/image_raw&type=ros_compressed'))))
        for name, make in runs:
            try:
                results[name] = measure(make(), args.seconds)
            except (OSError, EOFError, KeyError) as e:
                results[name] = {'error': f'{type(e).__name__}: {e}'}
            print(name, results[name], flush=True)
            time.sleep(1)
        if 'viewers' in only:
            for count in (1, 12):
                results[f'viewers-{count}'] = viewers_cpu(gw, count, args.seconds / 2)
                print(f'viewers-{count}', results[f'viewers-{count}'], flush=True)
            one, twelve = results['viewers-1']['gateway_cpu_percent'], results['viewers-12']['gateway_cpu_percent']
            results['cpu_ratio_12_to_1'] = round(twelve / one, 2) if one else None
            print('cpu ratio 12 viewers / 1 viewer:', results['cpu_ratio_12_to_1'])
    finally:
        cam.stop()
        gw.stop()
    save(args.out, results)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
