"""web_video_server's URLs on the gateway's port, so a page written for it works with only the
host and port changed:

GET /stream?topic=T&type=mjpeg|ros_compressed|png&width=&height=&quality=&qos_profile=
GET /snapshot?topic=T&width=&height=&quality=     one JPEG (the next frame)
GET /stream_viewer?topic=T&type=...               a page with the stream in an <img>
GET /streams                                      the list page (web_video_server's ``/``; here
                                                  ``/`` is the IDE)

The bytes are web_video_server's (src/multipart_stream.cpp, web_video_server.cpp): an HTTP/1.0
reply with ``Content-type: multipart/x-mixed-replace;boundary=boundarydonotcross``, then per
frame ``Content-type``, ``X-Timestamp`` (the header stamp, ``%.06f`` seconds) and
``Content-Length`` headers, the image, and ``\\r\\n--boundarydonotcross\\r\\n``. A base topic
with only ``T/compressed`` streams that one; ``ros_compressed`` passes the topic's JPEG bytes
as they are (and falls back to mjpeg without a compressed topic, as web_video_server does).

What differs, on purpose:
- one source per (topic, size, quality): the fan-out renders each frame once for all viewers
  (web_video_server encodes once per viewer);
- a viewer holds at most one frame waiting: while its connection is busy a newer frame
  replaces the waiting one, and the kernel's unsent share is bounded (``bound_unsent``), so a
  slow viewer gets fresh frames, never a backlog (web_video_server's queue on a slow link lags
  5-20 s);
- the rules of a subscribe: with --auth a token (``Authorization: Bearer``, the login cookie
  or ``?token=``), a role that may subscribe, and the topic globs; and no
  ``Access-Control-Allow-Origin: *`` (only without --auth, as web_video_server sends it);
- an unknown topic gets 404 within ``FIND_WAIT`` s (web_video_server keeps it open, empty);
- a closed viewer releases its source, and the last one the backend subscription.
``invert`` and ``default_transport`` are not supported; ``qos_profile`` is accepted and the
backend's own QoS matching used.
"""

from __future__ import annotations

import asyncio
import html
from typing import Protocol

import tornado.iostream
import tornado.web

from protocol.ops import MAX_IMAGE_SIDE

from ..media import images
from ..media.video import BOUNDARY, STALL, Video, Viewer
from ..rules.access import Area, may
from ..rules.policy import Policy
from .api import Handler, authorize, query_number
from .socket import bound_unsent

NO_CACHE = 'no-cache, no-store, must-revalidate, pre-check=0, post-check=0, max-age=0'
TYPES = ('mjpeg', 'ros_compressed', 'png')
SNAPSHOT_WAIT = 4.0     # s a snapshot waits for the next frame (then the last one, or 504)


class Graph(Protocol):
    """The backend's topics, as /streams lists them."""
    def topics(self, hidden: bool = False) -> list[tuple[str, str]]: ...


def reply_head(status: str, headers: list[tuple[str, str]]) -> bytes:
    """An HTTP/1.0 reply's head as async_web_server_cpp writes it."""
    return (f'HTTP/1.0 {status}\r\n' + ''.join(f'{k}: {v}\r\n' for k, v in headers) + '\r\n').encode()


class VideoHandler(Handler):
    """The checks in front of every video URL; the replies themselves are written on the
    detached connection, byte for byte as web_video_server writes them."""

    def initialize(self, video: Video, policy: Policy, graph: Graph) -> None:
        self.video, self.policy, self.graph = video, policy, graph

    def answer_error(self, status_code: int, reason: str) -> None:
        self.set_header('Content-Type', 'text/plain; charset=UTF-8')
        self.set_header('Cache-Control', 'no-store')
        self.finish(f'{status_code} {self._reason}: {reason}\n')

    @property
    def open_cors(self) -> bool:
        """web_video_server lets every origin read its images; only without --auth here."""
        return self.policy.auth is None

    def allowed(self, topic: str | None = None) -> None:
        """The rules of a subscribe: a token and a role that may subscribe (with --auth), and
        the topic globs (401/403 otherwise)."""
        identity = authorize(self, Area.VIDEO)
        why = may(self.policy, identity, 'subscribe', topic)
        if why is not None:
            raise tornado.web.HTTPError(403, why)

    def topic(self) -> str:
        topic = self.get_query_argument('topic', '').strip()
        if not topic:
            raise tornado.web.HTTPError(400, 'give the image topic: ?topic=/camera/image_raw')
        return topic if topic.startswith('/') else '/' + topic

    def kind(self) -> str:
        kind = self.get_query_argument('type', 'mjpeg')
        if kind not in TYPES:
            raise tornado.web.HTTPError(404, f'stream type {kind[:40]!r} is not served here ({", ".join(TYPES)})')
        return kind

    def number(self, name: str, default: int, low: int, high: int) -> int:
        return query_number(self, name, default, f'an integer from {low} to {high}', kind=int, low=low, high=high,
                            blank=('', '-1'))

    def target(self, kind: str) -> images.Target:
        width = self.number('width', 0, 1, MAX_IMAGE_SIDE) or None
        height = self.number('height', 0, 1, MAX_IMAGE_SIDE) or None
        if kind == 'png':
            return images.Target(width, height, self.number('quality', 3, 0, 9), 'png')
        return images.Target(width, height, self.number('quality', 95, 1, 100), 'jpeg')


class StreamHandler(VideoHandler):
    async def get(self) -> None:
        topic, kind = self.topic(), self.kind()
        self.allowed(topic)
        target = self.target('mjpeg' if kind == 'ros_compressed' else kind)
        name, type, passthrough = await self.video.find(topic, kind)
        self.allowed(name)
        headers = [('Connection', 'close'), ('Server', 'web_video_server'), ('Cache-Control', NO_CACHE),
                   ('Pragma', 'no-cache'), ('Content-type', f'multipart/x-mixed-replace;boundary={BOUNDARY}')]
        if self.open_cors:
            headers.append(('Access-Control-Allow-Origin', '*'))
        stream = self.detach()
        bound_unsent(stream)
        viewer = Viewer(stream)
        source = self.video.source(name, type, None if passthrough else target)
        source.viewers.add(viewer)
        closer = asyncio.ensure_future(viewer.watch_close())
        try:
            if await viewer.write(reply_head('200 OK', headers) + f'--{BOUNDARY}\r\n'.encode()):
                while not viewer.closed:
                    part = await viewer.next()
                    if part is None or not await viewer.write(part.wire):
                        break
        finally:
            source.remove(viewer)
            closer.cancel()
            stream.close()


class SnapshotHandler(VideoHandler):
    async def get(self) -> None:
        topic = self.topic()
        self.allowed(topic)
        target = self.target('mjpeg')
        name, type, _ = await self.video.find(topic, 'mjpeg')
        self.allowed(name)
        viewer = Viewer(None)
        source = self.video.source(name, type, target)
        source.viewers.add(viewer)
        try:
            part = await viewer.next(SNAPSHOT_WAIT)
            if part is None and source.fan.last is not None:   # a slow camera: its last frame
                try:
                    part = source.part(source.fan.last)
                except images.ImageError as e:
                    source.problem = str(e)
        finally:
            source.remove(viewer)
        if part is None:
            why = f': {source.problem}' if source.problem else ''
            raise tornado.web.HTTPError(504, f'no image on {name} within {SNAPSHOT_WAIT:g} s{why}')
        headers = [('Connection', 'close'), ('Server', 'web_video_server'), ('Cache-Control', NO_CACHE),
                   ('X-Timestamp', part.stamp), ('Pragma', 'no-cache'), ('Content-type', part.content_type)]
        if self.open_cors:
            headers.append(('Access-Control-Allow-Origin', '*'))
        headers.append(('Content-Length', str(len(part.data))))
        await _send_and_close(self.detach(), reply_head('200 OK', headers) + part.data)


class ViewerPageHandler(VideoHandler):
    async def get(self) -> None:
        topic, kind = self.get_query_argument('topic', ''), self.kind()
        self.allowed(topic if topic.startswith('/') else '/' + topic)
        query = self.request.query
        page = (f'<html><head><title>{html.escape(topic)}</title></head><body>'
                f'<h1>{html.escape(topic)}</h1><img src="/stream?{_attribute_safe(query)}"></img></body></html>')
        head = reply_head('200 OK', [('Connection', 'close'), ('Server', 'web_video_server'),
                                     ('Content-type', 'text/html;')])
        await _send_and_close(self.detach(), head + page.encode())


class ListHandler(VideoHandler):
    async def get(self) -> None:
        self.allowed()
        types = {name: type for name, type in self.graph.topics() if may(self.policy, None, 'subscribe', name) is None}
        head = reply_head('200 OK', [('Connection', 'close'), ('Server', 'web_video_server'),
                                     ('Cache-Control', NO_CACHE), ('Pragma', 'no-cache'),
                                     ('Content-type', 'text/html;')])
        await _send_and_close(self.detach(), head + list_page(types).encode())


def list_page(types: dict[str, str]) -> str:
    """web_video_server's list: image topics grouped under the base of each ``camera_info``,
    then the rest. Besides its sensor_msgs Image topics, the base of a compressed topic with no
    raw one (``/cam/image_raw`` for ``/cam/image_raw/compressed``), which /stream serves here."""
    image_topics = [n for n, t in sorted(types.items()) if t == images.RAW]
    for name, type in sorted(types.items()):
        base = name[:-len('/compressed')]
        if type == images.COMPRESSED and name.endswith('/compressed') and base not in types:
            image_topics.append(base)
    infos = [n for n, t in sorted(types.items()) if t == 'sensor_msgs/msg/CameraInfo']

    def item(topic: str, label: str) -> str:
        t = html.escape(topic)
        return (f'<li><a href="/stream_viewer?topic={t}">{html.escape(label)}</a> ('
                f'<a href="/stream?topic={t}">Stream</a>) (<a href="/snapshot?topic={t}">Snapshot</a>)</li>')

    out = ['<html><head><title>ROS Image Topic List</title></head><body><h1>Available ROS Image Topics:</h1>', '<ul>']
    for info in infos:
        if info.endswith('/camera_info'):
            base = info[:-len('camera_info')]
            out.append('<li>' + html.escape(base) + '<ul>')
            for topic in [t for t in image_topics if t.startswith(base)]:
                out.append(item(topic, topic[len(base):]))
                image_topics.remove(topic)
            out.append('</ul>')
        out.append('</li>')
    out.append('</ul><ul>')
    out += [item(topic, topic) for topic in image_topics]
    out.append('</ul></body></html>')
    return ''.join(out)


def _attribute_safe(query: str) -> str:
    """The query as web_video_server puts it in the page, except the characters that would end
    the attribute or open a tag, percent-encoded (a browser's own query never has them raw)."""
    return query.replace('"', '%22').replace('<', '%3C').replace('>', '%3E')


async def _send_and_close(stream, data: bytes) -> None:
    try:
        await asyncio.wait_for(stream.write(data), STALL)
    except (tornado.iostream.StreamClosedError, asyncio.TimeoutError):
        pass
    finally:
        stream.close()


def video_routes(video: Video, policy: Policy, graph: Graph) -> list:
    kw = {'video': video, 'policy': policy, 'graph': graph}
    return [(r'/stream', StreamHandler, kw), (r'/snapshot', SnapshotHandler, kw),
            (r'/stream_viewer', ViewerPageHandler, kw), (r'/streams', ListHandler, kw)]
