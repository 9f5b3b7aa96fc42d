"""One backend subscription per topic, shared by every client subscribed to it.

Each incoming message is encoded at most once per (compression, fragment_size, image) and the
same frames are queued to every subscriber's outbox; throttle_rate and queue_length are applied
per subscriber at its queue (a throttled MarkerArray stream is merged rather than thinned:
markers.py). An image made to measure (the ``image`` field of subscribe, the
``/stream`` viewers; a point cloud's ``points``: clouds.py) is rendered once per message and ``images.Target`` for all who asked, off
the event loop (``Renderer``): a 640x480 JPEG made 320 wide takes ~5-13 ms and a 1080p raw image
~70-90 ms here, which at 30 Hz would stall every client; Pillow lets go of the GIL while it
decodes, resizes and encodes, so a thread does it beside the loop. A message that arrives while
its target still renders waits in its place (newest-wins): a camera faster than the renderer
loses frames, never gains latency.

Sensor streams (``NEWEST_WINS``: images, point clouds, scans, poses, odometry) keep only their
newest message queued for a client that falls behind, whatever queue_length it asked: each
message is the whole state, so one that waited behind a newer one is only latency (a 10 Hz
camera over 1 Mbit/s grew 5 s -> 16 s old with the default queue). Marker arrays are not among
them: the world view sends increments (pen batches), and a dropped one is a lost trail.
"""

from __future__ import annotations

import asyncio
import functools
import itertools
import logging
import time
from typing import TYPE_CHECKING, Any

from protocol.ops import ImageSpec

from ..media import images
from . import clouds, encode, markers

if TYPE_CHECKING:
    from .session import ClientSession

log = logging.getLogger('rosgate.fanout')
_fragment_ids = itertools.count(1)
# encodings made from the message's CDR: rosbridge's cbor-raw, and 'cdr', the bytes alone, which
# the Foxglove sessions' subscriptions take (bridge.foxglove.topics.Feed frames them)
CDR_ENCODINGS = ('cbor-raw', 'cdr')
NEWEST_WINS = frozenset({
    images.RAW, images.COMPRESSED, 'sensor_msgs/msg/PointCloud2', 'sensor_msgs/msg/LaserScan',
    'geometry_msgs/msg/PoseStamped', 'geometry_msgs/msg/Pose',
    'geometry_msgs/msg/PoseWithCovarianceStamped', 'nav_msgs/msg/Odometry', 'turtlesim/msg/Pose',
    'nav_msgs/msg/OccupancyGrid',
})


def made(msg: dict, type: str, target) -> bytes | dict:
    """A message made to measure: a cloud thinned (clouds.py), an image or a map fitted (images.py)."""
    if isinstance(target, clouds.Target):
        return clouds.thin(msg, target.points)
    return images.render(msg, type, target)


class Subscriber:
    """One client's subscription to one topic (all its subscribe ids merged, as rosbridge does)."""

    __slots__ = ('session', 'fanout', 'options', 'compression', 'fragment_size', 'throttle',
                 'queue_length', 'last_sent', 'pending', 'timer', 'key', 'image')

    def __init__(self, session: ClientSession, fanout: TopicFanout):
        self.session, self.fanout = session, fanout
        self.options: dict[str | None, tuple] = {}   # subscribe id -> (throttle_ms, queue_length, compression, fragment_size, image)
        self.last_sent = 0.0
        self.pending = None
        self.timer = None
        self.key = (fanout.topic, session.id)
        self.compression, self.fragment_size, self.throttle, self.queue_length = 'none', None, 0.0, 0
        self.image: images.Target | None = None

    def update(self, default_queue_length: int) -> None:
        opts = list(self.options.values())
        self.throttle = min(o[0] for o in opts) / 1000.0
        lengths = [o[1] for o in opts]
        self.queue_length = 1 if self.fanout.type in NEWEST_WINS else max(lengths) or default_queue_length
        self.compression, self.fragment_size = opts[-1][2], opts[-1][3]
        spec = opts[-1][4] if len(opts[-1]) > 4 else None   # an ImageSpec, a clouds.Target or None
        self.image = images.Target.of(spec) if isinstance(spec, ImageSpec) else spec

    def deliver(self, frames: encode.Frames) -> None:
        outbox = self.session.outbox
        keep = max(self.queue_length, len(frames))   # a fragmented message is kept whole
        for payload, binary in frames:
            outbox.message(payload, binary, self.key, keep)

    def cancel(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None
        self.session.outbox.forget(self.key)


class Renderer:
    """One Target of one topic's images, rendered in the loop's default executor, newest-wins."""

    def __init__(self, fanout: TopicFanout, target: images.Target):
        self.fanout, self.target = fanout, target
        self.busy = False
        self.waiting: dict | None = None

    def submit(self, msg: dict) -> None:
        if self.busy:
            self.waiting = msg   # replaces any message waiting before it
            return
        self.busy = True
        future = asyncio.get_running_loop().run_in_executor(None, made, msg, self.fanout.type, self.target)
        future.add_done_callback(functools.partial(self._done, msg))

    def _done(self, msg: dict, future: asyncio.Future) -> None:
        self.busy = False
        fan = self.fanout
        if fan.closed or future.cancelled():
            return
        try:
            result: bytes | dict | images.ImageError = future.result()
        except images.ImageError as e:
            result = e
        except Exception as e:   # a bug or a Pillow failure past decoding: said, never raised into the loop
            log.exception('rendering %s failed', fan.topic)
            result = images.ImageError(f'cannot render the image: {e}')
        fan.renders += 1
        fan.gateway.images_rendered += 1
        fan.rendered(self.target, msg, result)
        waiting, self.waiting = self.waiting, None
        if waiting is not None and not fan.closed:
            self.submit(waiting)


class TopicFanout:
    def __init__(self, gateway, topic: str, type: str):
        self.gateway, self.topic, self.type = gateway, topic, type
        backend = gateway.backend
        self.msgdef = backend.msg_def(type)
        self.subscribers: dict[int, Subscriber] = {}
        self.watchers: dict[object, tuple] = {}   # key -> (callback(msg, image), Target or None)
        self.last: dict | None = None
        self.merges = type == markers.MARKER_ARRAY   # throttled: merged, not dropped (markers.py)
        self.renderers: dict[images.Target, Renderer] = {}
        self.renders = 0   # images rendered: at most one per message and target, however many take it
        self.closed = False
        self.meter = None   # topicstats.Meter while a page is shown this topic's rate (it keeps the fan-out)
        self.handle = backend.subscribe(topic, type, self._on_message, cdr=True)
        self._cdr_wanted = False    # a subscriber takes cbor-raw: the backend keeps the CDR as received

    def add(self, session: ClientSession, sid: str | None, options: tuple) -> Subscriber:
        """Add or change one subscribe id; on failure the subscriber is as it was (or absent)."""
        sub = self.subscribers.get(session.id) or Subscriber(session, self)
        before = sub.options.get(sid)
        sub.options[sid] = options
        try:
            sub.update(self.gateway.settings.default_queue_length)
        except BaseException:
            if before is None:
                del sub.options[sid]
            else:
                sub.options[sid] = before
            if sub.options:
                sub.update(self.gateway.settings.default_queue_length)
            raise
        self.subscribers[session.id] = sub
        self._want_cdr()
        return sub

    def remove(self, session: ClientSession, sid: str | None) -> bool:
        """Remove one subscribe id (or all with None); True once the client has none left."""
        sub = self.subscribers.get(session.id)
        if sub is None:
            return True
        if sid in sub.options:
            del sub.options[sid]
        else:   # no id, or one we never saw: the client means all of its subscriptions
            sub.options.clear()
        if sub.options:
            sub.update(self.gateway.settings.default_queue_length)
            self._want_cdr()
            return False
        sub.cancel()
        del self.subscribers[session.id]
        if self.unused:
            self.gateway.drop_fanout(self)
        else:
            self._want_cdr()
        return True

    def watch(self, key: object, callback, target: images.Target | None = None) -> None:
        """``callback(msg, image)`` for each message, beside the subscribers (a ``/stream``
        source): image is None without a target, else the rendered bytes or an ImageError."""
        self.watchers[key] = (callback, target)

    def unwatch(self, key: object) -> None:
        if self.watchers.pop(key, None) is not None and self.unused:
            self.gateway.drop_fanout(self)

    def unmeter(self, meter) -> None:
        """The topic is no longer measured (topicstats); the subscription goes if nobody else has it."""
        if self.meter is meter:
            self.meter = None
            if self.unused and not self.closed:
                self.gateway.drop_fanout(self)

    @property
    def unused(self) -> bool:
        return not self.subscribers and not self.watchers and self.meter is None

    def _want_cdr(self) -> None:
        wanted = any(sub.compression in CDR_ENCODINGS for sub in self.subscribers.values())
        if wanted != self._cdr_wanted:
            self._cdr_wanted = wanted
            self.handle.want_cdr(wanted)

    def destroy(self) -> None:
        for sub in self.subscribers.values():
            sub.cancel()
        self.subscribers.clear()
        self.watchers.clear()
        self.renderers.clear()
        self.closed = True
        self.handle.destroy()

    # --- the hot path -----------------------------------------------------------------------

    def replay_latched(self, sub: Subscriber) -> None:
        """A client joining a shared subscription still gets a latched topic's retained messages
        (what the backend holds for late subscribers when it can tell, else the last message)."""
        backend = self.gateway.backend
        if self.last is None or not backend.latched(self.topic):
            return   # a new shared subscription: the backend delivers the retained messages itself
        for msg in backend.latched_messages(self.topic) or [self.last]:
            sub.last_sent = time.monotonic()
            if sub.image is None:
                sub.deliver(self._encode(msg, sub.compression, sub.fragment_size))
            else:   # rare (a latched camera): rendered here, for this subscriber alone
                try:
                    result: bytes | dict | images.ImageError = made(msg, self.type, sub.image)
                except images.ImageError as e:
                    result = e
                sub.deliver(self._encode_image(msg, result, sub.compression, sub.fragment_size))

    def _on_message(self, msg: dict, cdr: bytes | None = None) -> None:
        """cdr: the message as the backend received it, for cbor-raw (else built from msg)."""
        self.last = msg
        if self.meter is not None:
            self.meter.count(msg, cdr)
        cache: dict[tuple, encode.Frames] = {}
        now = time.monotonic()
        targets: set[images.Target] = set()
        for sub in tuple(self.subscribers.values()):
            if sub.image is not None:   # rendered first; throttled and sent in rendered()
                targets.add(sub.image)
                continue
            if sub.throttle:
                if now - sub.last_sent < sub.throttle:
                    if self.merges:   # increments: every change kept, the newest of each marker
                        self._hold(sub, (markers.merge(sub.pending and sub.pending[0], msg), None), now)
                    else:
                        self._hold(sub, (msg, cdr), now)
                    continue
                sub.last_sent = now
            key = (sub.compression, sub.fragment_size)
            frames = cache.get(key)
            if frames is None:
                frames = cache[key] = self._encode(msg, sub.compression, sub.fragment_size, cdr)
            sub.deliver(frames)
        for callback, target in tuple(self.watchers.values()):
            if target is None:
                callback(msg, None)
            else:
                targets.add(target)
        if targets or self.renderers:
            self.renderers = {t: self.renderers.get(t) or Renderer(self, t) for t in targets}
            for renderer in self.renderers.values():
                renderer.submit(msg)

    def rendered(self, target: images.Target, msg: dict, result: bytes | images.ImageError) -> None:
        """A message's image made to ``target`` (or why not): to its subscribers, each as its
        throttle_rate lets, and to the watchers that asked for it."""
        cache: dict[tuple, encode.Frames] = {}
        now = time.monotonic()
        for sub in tuple(self.subscribers.values()):
            if sub.image != target:
                continue
            if sub.throttle:
                if now - sub.last_sent < sub.throttle:
                    self._hold(sub, (msg, result, 'image'), now)
                    continue
                sub.last_sent = now
            key = (sub.compression, sub.fragment_size)
            frames = cache.get(key)
            if frames is None:
                frames = cache[key] = self._encode_image(msg, result, *key)
            sub.deliver(frames)
        for callback, wanted in tuple(self.watchers.values()):
            if wanted == target:
                callback(msg, result)

    def _hold(self, sub: Subscriber, pending: tuple, now: float) -> None:
        """A throttled subscriber keeps the latest; it is sent when the period ends (``_flush``)."""
        sub.pending = pending
        if sub.timer is None:
            delay = sub.throttle - (now - sub.last_sent)
            sub.timer = asyncio.get_running_loop().call_later(delay, self._flush, sub)

    def _flush(self, sub: Subscriber) -> None:
        sub.timer = None
        pending, sub.pending = sub.pending, None
        if pending is not None and sub.session.id in self.subscribers:
            sub.last_sent = time.monotonic()
            if len(pending) == 3:   # (msg, its rendered image, 'image')
                sub.deliver(self._encode_image(pending[0], pending[1], sub.compression, sub.fragment_size))
            else:                       # (msg, cdr)
                sub.deliver(self._encode(pending[0], sub.compression, sub.fragment_size, pending[1]))

    def _encode_image(self, msg: dict, result: bytes | images.ImageError, compression: str,
                      fragment_size: int | None) -> encode.Frames:
        """A CompressedImage made to measure, whatever the topic's image type (or a warning); a
        map made smaller stays a map of the topic's type."""
        if isinstance(result, images.ImageError):
            return encode.frames({'op': 'status', 'level': 'warning', 'msg': f'{self.topic}: {result}'})
        if isinstance(result, dict):
            return self._encode(result, compression, fragment_size)
        made = {'header': msg.get('header', {}), 'format': 'jpeg', 'data': result}
        return self._encode(made, compression, fragment_size, msgdef=self.gateway.backend.msg_def(images.COMPRESSED))

    def _encode(self, msg: dict, compression: str, fragment_size: int | None,
                cdr: bytes | None = None, msgdef=None) -> encode.Frames:
        msgdef = msgdef or self.msgdef
        if compression == 'cdr':   # a Foxglove subscription: the bytes alone, framed per subscriber (Feed)
            return [(cdr if cdr is not None else self.gateway.backend.to_cdr(self.type, msg), True)]
        if compression == 'cbor-raw':
            sec, nanosec = self.gateway.backend.now()
            if cdr is None:
                cdr = self.gateway.backend.to_cdr(self.type, msg)
            body: Any = {'secs': sec, 'nsecs': nanosec, 'bytes': cdr}
            return encode.frames({'op': 'publish', 'topic': self.topic, 'msg': body}, 'cbor-raw')
        op = {'op': 'publish', 'topic': self.topic, 'msg': msg}
        if fragment_size or compression == 'png':
            op['id'] = f'publish:{self.topic}:{next(_fragment_ids)}'
        return encode.frames(op, compression, fragment_size, msgdef=msgdef, defs=self.gateway.backend.defs)
