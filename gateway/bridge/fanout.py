"""One backend subscription per topic, shared by every client subscribed to it.

Each incoming message is encoded at most once per (compression, fragment_size, image) and the
same frames are queued to every subscriber's outbox; throttle_rate and queue_length are applied
per subscriber at its queue. An image made to measure (the ``image`` field of subscribe, the
``/stream`` viewers) is rendered once per message and ``images.Target`` for all who asked.

Sensor streams (``NEWEST_WINS``: images, point clouds, scans, poses, odometry) keep only their
newest message queued for a client that falls behind, whatever queue_length it asked: each
message is the whole state, so one that waited behind a newer one is only latency (a 10 Hz
camera over 1 Mbit/s grew 5 s -> 16 s old with the default queue). Marker arrays are not among
them: the world view sends increments (pen batches), and a dropped one is a lost trail.
"""

from __future__ import annotations

import asyncio
import itertools
import time
from typing import TYPE_CHECKING, Any

from . import encode, images

if TYPE_CHECKING:
    from .session import ClientSession

_fragment_ids = itertools.count(1)
NEWEST_WINS = frozenset({
    images.RAW, images.COMPRESSED, 'sensor_msgs/msg/PointCloud2', 'sensor_msgs/msg/LaserScan',
    'geometry_msgs/msg/PoseStamped', 'geometry_msgs/msg/Pose',
    'geometry_msgs/msg/PoseWithCovarianceStamped', 'nav_msgs/msg/Odometry', 'turtlesim/msg/Pose',
})


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
        spec = opts[-1][4] if len(opts[-1]) > 4 else None
        self.image = images.Target.of(spec) if spec is not None else None

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


class TopicFanout:
    def __init__(self, gateway, topic: str, type: str):
        self.gateway, self.topic, self.type = gateway, topic, type
        backend = gateway.backend
        self.msgdef = backend.msg_def(type)
        self.subscribers: dict[int, Subscriber] = {}
        self.watchers: dict[object, object] = {}   # key -> callable(msg): takers of the message itself
        self.last: dict | None = None
        self._rendered: dict[images.Target, bytes | images.ImageError] = {}   # for _rendered_msg
        self._rendered_msg: dict | None = None
        self.renders = 0   # images rendered: one per message and target, however many take it
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
        if not self.subscribers and not self.watchers:
            self.gateway.drop_fanout(self)
        else:
            self._want_cdr()
        return True

    def watch(self, key: object, callback) -> None:
        """``callback(msg)`` for each message, beside the subscribers (a ``/stream`` source)."""
        self.watchers[key] = callback

    def unwatch(self, key: object) -> None:
        if self.watchers.pop(key, None) is not None and not self.subscribers and not self.watchers:
            self.gateway.drop_fanout(self)

    def render(self, msg: dict, target: images.Target) -> bytes:
        """The message's image made to ``target``, rendered once per message and target for all
        who ask (raises images.ImageError, also once)."""
        if self._rendered_msg is not msg:
            self._rendered_msg, self._rendered = msg, {}
        done = self._rendered.get(target)
        if done is None:
            try:
                done = images.render(msg, self.type, target)
            except images.ImageError as e:
                done = e
            self._rendered[target] = done
            self.renders += 1
            self.gateway.images_rendered += 1
        if isinstance(done, images.ImageError):
            raise done
        return done

    def _want_cdr(self) -> None:
        wanted = any(sub.compression == 'cbor-raw' for sub in self.subscribers.values())
        if wanted != self._cdr_wanted:
            self._cdr_wanted = wanted
            self.handle.want_cdr(wanted)

    def destroy(self) -> None:
        for sub in self.subscribers.values():
            sub.cancel()
        self.subscribers.clear()
        self.watchers.clear()
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
            sub.deliver(self._encode(msg, sub.compression, sub.fragment_size, None, sub.image))

    def _on_message(self, msg: dict, cdr: bytes | None = None) -> None:
        """cdr: the message as the backend received it, for cbor-raw (else built from msg)."""
        self.last = msg
        cache: dict[tuple, encode.Frames] = {}
        now = time.monotonic()
        for sub in tuple(self.subscribers.values()):
            if sub.throttle:
                if now - sub.last_sent < sub.throttle:
                    sub.pending = (msg, cdr)   # keep the latest; sent when the period ends
                    if sub.timer is None:
                        delay = sub.throttle - (now - sub.last_sent)
                        sub.timer = asyncio.get_running_loop().call_later(delay, self._flush, sub)
                    continue
                sub.last_sent = now
            key = (sub.compression, sub.fragment_size, sub.image)
            frames = cache.get(key)
            if frames is None:
                frames = cache[key] = self._encode(msg, sub.compression, sub.fragment_size, cdr, sub.image)
            sub.deliver(frames)
        for watcher in tuple(self.watchers.values()):
            watcher(msg)

    def _flush(self, sub: Subscriber) -> None:
        sub.timer = None
        pending, sub.pending = sub.pending, None
        if pending is not None and sub.session.id in self.subscribers:
            sub.last_sent = time.monotonic()
            sub.deliver(self._encode(pending[0], sub.compression, sub.fragment_size, pending[1], sub.image))

    def _encode(self, msg: dict, compression: str, fragment_size: int | None,
                cdr: bytes | None = None, image: images.Target | None = None) -> encode.Frames:
        msgdef = self.msgdef
        if image is not None:   # a CompressedImage made to measure, whatever the topic's image type
            try:
                data = self.render(msg, image)
            except images.ImageError as e:
                return encode.frames({'op': 'status', 'level': 'warning', 'msg': f'{self.topic}: {e}'})
            msg = {'header': msg.get('header', {}), 'format': 'jpeg', 'data': data}
            msgdef = self.gateway.backend.msg_def(images.COMPRESSED)
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
