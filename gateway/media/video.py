"""Camera streams as web_video_server serves them (the URLs are ``web.video``'s): a ``Source`` per
topic at one size and quality, watched in the topic's shared fan-out while it has viewers, so each
frame is rendered once for all of them; a ``Viewer`` per connection holding at most one frame (a
newer one replaces it), so a slow viewer gets fresh frames, never a backlog; and ``Video.find``, the
image topic a stream of a kind takes (``T`` or ``T/compressed``), waiting ``FIND_WAIT`` s for a
camera that is starting.
"""

from __future__ import annotations

import asyncio
import itertools

import tornado.iostream

from ..rules.errors import Refusal
from . import images
from .ports import Graph, Taps

BOUNDARY = 'boundarydonotcross'
FIND_WAIT = 2.0         # s an unknown topic is looked for (a camera node starting) before 404
STALL = 30.0            # s a viewer's write may take before the viewer is given up (a vanished peer)
_keys = itertools.count(1)


class Part:
    """One frame as every viewer of a source sends it: headers, image and the next boundary,
    joined once."""

    __slots__ = ('wire', 'content_type', 'stamp', 'data')

    def __init__(self, content_type: str, stamp: str, data: bytes):
        self.content_type, self.stamp, self.data = content_type, stamp, data
        head = (f'Content-type: {content_type}\r\nX-Timestamp: {stamp}\r\n'
                f'Content-Length: {len(data)}\r\n\r\n')
        self.wire = b''.join((head.encode(), data, f'\r\n--{BOUNDARY}\r\n'.encode()))


def stamp_of(msg: dict) -> str:
    """rclcpp::Time(header.stamp).seconds() printed as web_video_server prints it ("%.06lf")."""
    stamp = (msg.get('header') or {}).get('stamp') or {}
    nanos = int(stamp.get('sec', 0)) * 10**9 + int(stamp.get('nanosec', 0))
    return '%.06f' % (nanos / 1e9)


class Source:
    """One topic at one Target (None: the topic's own compressed bytes), watched in the topic's
    fan-out while it has viewers."""

    def __init__(self, video: Video, topic: str, type: str, target: images.Target | None):
        self.video, self.topic, self.type, self.target = video, topic, type, target
        self.viewers: set = set()
        self.problem: str | None = None   # why the last frame could not be made
        self.key = ('video', next(_keys))
        self.fan = video.taps.fanout(topic, type)
        self.fan.watch(self.key, self._on_message, target)

    def part(self, msg: dict, image: bytes | images.ImageError | None = None) -> Part:
        """The message as this source's frame, from its image as the fan-out rendered it (or
        rendered here when not given: a snapshot of the last message); raises images.ImageError."""
        if self.target is None:
            kind = images.content_type(msg)
            if kind is None:
                raise images.ImageError(f'unknown compressed format {msg.get("format")!r}')
            return Part(kind, stamp_of(msg), bytes(msg.get('data') or b''))
        if image is None:
            image = images.render(msg, self.type, self.target)
        if isinstance(image, images.ImageError):
            raise image
        return Part('image/png' if self.target.format == 'png' else 'image/jpeg', stamp_of(msg), image)

    def _on_message(self, msg: dict, image: bytes | images.ImageError | None) -> None:
        try:
            part = self.part(msg, image)
        except images.ImageError as e:
            self.problem = str(e)
            return
        self.problem = None
        for viewer in tuple(self.viewers):
            viewer.offer(part)

    def remove(self, viewer) -> None:
        self.viewers.discard(viewer)
        if not self.viewers:
            self.video.sources.pop((self.topic, self.target), None)
            self.fan.unwatch(self.key)


class Viewer:
    """One connection taking frames from a source: at most one frame waits for it."""

    def __init__(self, stream: tornado.iostream.IOStream):
        self.stream = stream
        self.waiting: Part | None = None
        self.ready = asyncio.Event()
        self.closed = False

    def offer(self, part: Part) -> None:
        self.waiting = part   # a frame not yet sent is replaced: newest wins
        self.ready.set()

    async def next(self, timeout: float | None = None) -> Part | None:
        """The newest frame once there is one (None: the connection closed, or timeout)."""
        try:
            await asyncio.wait_for(self.ready.wait(), timeout)
        except asyncio.TimeoutError:
            return None
        self.ready.clear()
        part, self.waiting = self.waiting, None
        return None if self.closed else part

    async def watch_close(self) -> None:
        """Read (and drop) whatever the client sends until it closes: without a pending read
        the stream would not notice a viewer that went away while no frame flows."""
        try:
            while True:
                await self.stream.read_bytes(4096, partial=True)
        except tornado.iostream.StreamClosedError:
            pass
        finally:
            self.closed = True
            self.ready.set()

    async def write(self, data: bytes) -> bool:
        """False when the viewer is gone (closed, or not taking data for STALL s)."""
        if self.closed:
            return False
        try:
            future = self.stream.write(data)
        except tornado.iostream.StreamClosedError:
            return False
        done, _ = await asyncio.wait({future}, timeout=STALL)
        if not done:
            return False
        return future.exception() is None


class Video:
    """The sources streamed now, each watching its topic's fan-out (``taps``); the image topics
    found in ``graph``."""

    def __init__(self, taps: Taps, graph: Graph):
        self.taps, self.graph = taps, graph
        self.sources: dict[tuple, Source] = {}

    def source(self, topic: str, type: str, target: images.Target | None) -> Source:
        src = self.sources.get((topic, target))
        if src is None:
            src = self.sources[(topic, target)] = Source(self, topic, type, target)
        return src

    async def find(self, topic: str, kind: str) -> tuple[str, str, bool]:
        """(topic to watch, its type, pass its bytes through) for a stream of ``kind``; 404 when
        there is no such image topic within FIND_WAIT s."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + FIND_WAIT
        while True:
            types = dict(self.graph.topics())
            found = pick(types, topic, kind)
            if found is not None:
                return found
            if topic in types:
                raise Refusal(404, f'{topic} is {types[topic]}, not an image topic '
                              f'({" or ".join(images.TYPES)})')
            if loop.time() >= deadline:
                raise Refusal(404, f'no image topic {topic} (nor {topic}/compressed)')
            await asyncio.sleep(0.1)


def pick(types: dict[str, str], topic: str, kind: str) -> tuple[str, str, bool] | None:
    compressed = topic.rstrip('/') + '/compressed'
    if kind == 'ros_compressed':
        if types.get(compressed) == images.COMPRESSED:
            return compressed, images.COMPRESSED, True
        if types.get(topic) == images.COMPRESSED:
            return topic, images.COMPRESSED, True
    if types.get(topic) in images.TYPES:
        return topic, types[topic], False
    if types.get(compressed) == images.COMPRESSED:
        return compressed, images.COMPRESSED, False
    return None
