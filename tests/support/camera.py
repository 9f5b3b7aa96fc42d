"""A test camera and a web_video_server client: a roslibpy publisher of 640x480 JPEG
CompressedImages at 10 Hz stamped with the wall clock, and a raw-socket reader of
``multipart/x-mixed-replace`` streams that checks every byte it parses."""

from __future__ import annotations

import base64
import io
import re
import socket
import threading
import time
from contextlib import contextmanager

import numpy as np
from PIL import Image

from tests.support.ros import client
from tests.support.wait import wait_for

BOUNDARY = b'boundarydonotcross'
PART = re.compile(rb'Content-type: (image/[a-z]+)\r\nX-Timestamp: (\d+\.\d{6})\r\nContent-Length: (\d+)\r\n\r\n')


def frames(count: int = 8, width: int = 640, height: int = 480) -> list[bytes]:
    """Distinct JPEGs of a camera-like scene (gradients, a moving block, some noise): ~40 KiB."""
    rng = np.random.default_rng(7)
    y, x = np.mgrid[0:height, 0:width]
    out = []
    for i in range(count):
        img = np.stack([(x * 255 // width), (y * 255 // height), np.full_like(x, 40 + 20 * i)], -1).astype(np.int16)
        img[100:200, 40 + 60 * i:140 + 60 * i] = (250, 250, 250)
        img += rng.integers(-18, 18, img.shape, dtype=np.int16)
        buf = io.BytesIO()
        Image.fromarray(img.clip(0, 255).astype(np.uint8), 'RGB').save(buf, 'JPEG', quality=80)
        out.append(buf.getvalue())
    return out


class Camera:
    """Publishes ``topic`` (sensor_msgs/CompressedImage) at ``rate`` Hz from a thread, each message
    stamped with time.time(); ``sent`` maps its stamp (as X-Timestamp prints it) to its bytes."""

    def __init__(self, ros, topic: str = '/cam/image_raw/compressed', rate: float = 10.0):
        import roslibpy
        self.images = frames()
        self.topic = roslibpy.Topic(ros, topic, 'sensor_msgs/msg/CompressedImage')
        self.topic.advertise()
        self.rate, self.sent, self.count = rate, {}, 0
        self.stop = threading.Event()
        self.roslibpy = roslibpy
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        period = 1.0 / self.rate
        next_at = time.monotonic()
        while not self.stop.is_set():
            data = self.images[self.count % len(self.images)]
            now = time.time_ns()
            sec, nanosec = divmod(now, 10**9)
            self.sent['%.06f' % (now / 1e9)] = data
            self.topic.publish(self.roslibpy.Message({
                'header': {'stamp': {'sec': sec, 'nanosec': nanosec}, 'frame_id': 'cam'},
                'format': 'jpeg', 'data': base64.b64encode(data).decode()}))
            self.count += 1
            next_at += period
            self.stop.wait(max(0.0, next_at - time.monotonic()))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)
        self.topic.unadvertise()


class Stream:
    """GET a URL on a raw socket and read its reply: ``head`` (status line and headers, bytes),
    then ``part()`` for each multipart frame, checked against web_video_server's framing."""

    def __init__(self, port: int, path: str, rcvbuf: int | None = None, headers: str = '', timeout: float = 10):
        self.sock = socket.socket()
        if rcvbuf:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.settimeout(timeout)
        self.sock.connect(('127.0.0.1', port))
        self.sock.sendall(f'GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n{headers}\r\n'.encode())
        self.buf = b''
        self.head = self._until(b'\r\n\r\n')

    def _fill(self) -> None:
        chunk = self.sock.recv(65536)
        if not chunk:
            raise EOFError(f'the connection closed; unread: {self.buf[:200]!r}')
        self.buf += chunk

    def _until(self, marker: bytes) -> bytes:
        while marker not in self.buf:
            self._fill()
        i = self.buf.index(marker) + len(marker)
        out, self.buf = self.buf[:i], self.buf[i:]
        return out

    def take(self, n: int) -> bytes:
        while len(self.buf) < n:
            self._fill()
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def body(self) -> bytes:
        """The reply's body: Content-Length bytes when the head gives it, else until the close."""
        m = re.search(rb'\r\nContent-Length: (\d+)\r\n', self.head, re.I)
        return self.take(int(m.group(1))) if m else self.rest()

    def rest(self) -> bytes:
        """Everything until the server closes."""
        while True:
            try:
                self._fill()
            except EOFError:
                return self.buf

    def opening(self) -> bytes:
        """The boundary line that follows the stream's headers."""
        return self.take(len(BOUNDARY) + 4)

    def part(self) -> tuple[str, str, bytes]:
        """(content type, X-Timestamp, image) of the next frame; fails on any other byte."""
        head = self._until(b'\r\n\r\n')
        m = PART.fullmatch(head)
        assert m, f'not a web_video_server part header: {head!r}'
        data = self.take(int(m.group(3)))
        tail = self.take(len(BOUNDARY) + 6)
        assert tail == b'\r\n--' + BOUNDARY + b'\r\n', tail
        return m.group(1).decode(), m.group(2).decode(), data

    def close(self) -> None:
        self.sock.close()


def stream_head(cors: bool) -> bytes:
    """The reply head web_video_server writes for /stream (src/multipart_stream.cpp)."""
    return (b'HTTP/1.0 200 OK\r\nConnection: close\r\nServer: web_video_server\r\n'
            b'Cache-Control: no-cache, no-store, must-revalidate, pre-check=0, post-check=0, max-age=0\r\n'
            b'Pragma: no-cache\r\nContent-type: multipart/x-mixed-replace;boundary=boundarydonotcross\r\n'
            + (b'Access-Control-Allow-Origin: *\r\n' if cors else b'') + b'\r\n')


@contextmanager
def running_camera(gw, topic: str = '/cam/image_raw/compressed'):
    """A Camera publishing to ``gw`` over a roslibpy connection of its own, its first frames sent."""
    with client(gw) as ros:
        cam = Camera(ros, topic)
        try:
            wait_for(lambda: cam.count >= 3, 10)
            yield cam
        finally:
            cam.close()
