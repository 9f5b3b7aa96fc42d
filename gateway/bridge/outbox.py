"""A bounded per-client send queue.

Replies (service responses, action results, status) are never dropped, but they are bounded
too: a client with more than ``reply_limit`` replies or ``byte_limit`` bytes of them waiting is
not reading what it asks for: everything queued is released at once (none of it will be sent)
and ``on_reply_overflow`` is told once (the session closes the connection with 1008). Topic
messages are dropped: each subscription keeps at most ``queue_length`` queued messages (oldest
dropped first, its frame released at once), and once the whole queue holds more than ``byte_limit`` bytes, new topic
messages are dropped and the client is warned (at most once per ``warn_interval``). A slow
client therefore loses its own oldest messages; it never grows server memory without bound nor
stalls anyone else. An outbox that held a lot gives the memory back to the system when it
closes.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import ctypes.util
import logging
from collections import deque
from collections.abc import Awaitable, Callable

log = logging.getLogger('rosgate')
BATCH_BYTES = 256 * 1024   # written to the socket before waiting for it to drain
REPLY_LIMIT = 4096         # replies queued for a client that does not read them
TRIM_AFTER = 4 * 2**20     # an outbox that held this many bytes returns memory when it closes


Frames = list[tuple[bytes, bool]]


class Entry:
    __slots__ = ('frame', 'binary', 'key', 'size', 'alive')

    def __init__(self, frame: bytes, binary: bool, key: object | None):
        self.frame, self.binary, self.key = frame, binary, key
        self.size = len(frame)
        self.alive = True


class Outbox:
    def __init__(self, write: Callable[[bytes, bool], Awaitable[None] | None],
                 write_many: Callable[[Frames], Awaitable[None] | None], *,
                 byte_limit: int = 16 * 2**20, on_overflow: Callable[[int], None] | None = None,
                 warn_interval: float = 5.0, reply_limit: int = REPLY_LIMIT,
                 on_reply_overflow: Callable[[int, int], None] | None = None):
        self._write = write          # ws.write_message(frame, binary=...) -> Future
        self._write_many = write_many   # several frames in one socket write -> Future
        self._held: Frames | None = None   # frames written while corked, not yet sent
        self._queue: deque[Entry] = deque()
        self._dead = 0               # dropped entries still in _queue (their frames released)
        self._per_key: dict[object, deque[Entry]] = {}
        self.byte_limit = byte_limit
        self.queued_bytes = 0
        self.peak_bytes = 0
        self.reply_limit = reply_limit
        self.reply_count = 0         # replies queued, not yet written
        self.reply_bytes = 0
        self._on_reply_overflow = on_reply_overflow
        self.dropped = 0
        self._on_overflow = on_overflow
        self._warn_interval = warn_interval
        self._last_warn = -1e9
        self._dropped_since_warn = 0
        self._wakeup = asyncio.Event()
        self.idle = asyncio.Event()  # set while nothing is queued (the pump has written it all)
        self.idle.set()
        self._closed = False
        self._task: asyncio.Task | None = None
        self._last_write = None      # Future of the latest write: done once the socket took it

    def start(self) -> None:
        self._task = asyncio.ensure_future(self._run())

    def close(self) -> None:
        self._closed = True
        self.idle.set()
        self._queue.clear()
        self._dead = 0
        self._per_key.clear()
        self.queued_bytes = self.reply_count = self.reply_bytes = 0
        self._wakeup.set()
        if self._task:
            self._task.cancel()
        if self.peak_bytes >= TRIM_AFTER:
            asyncio.get_running_loop().call_soon(release_memory)

    def reply(self, frame: bytes, binary: bool = False) -> None:
        """Queue a frame that must not be dropped (past the reply bound the client is given up)."""
        if self._closed:
            return
        if self._write_now(frame, binary):
            return
        if self.reply_count >= self.reply_limit or (
                self.reply_bytes and self.reply_bytes + len(frame) > self.byte_limit):
            count, size = self.reply_count, self.reply_bytes
            self.close()   # none of it will be sent: the memory goes back now, not at disconnect
            if self._on_reply_overflow is not None:
                self._on_reply_overflow(count, size)
            return
        entry = Entry(frame, binary, None)
        self._queue.append(entry)
        self.idle.clear()
        self.queued_bytes += entry.size
        self.reply_count += 1
        self.reply_bytes += entry.size
        if self.queued_bytes > self.peak_bytes:
            self.peak_bytes = self.queued_bytes
        self._wakeup.set()

    def message(self, frame: bytes, binary: bool, key: object, queue_length: int) -> bool:
        """Queue a topic message for subscription ``key``; False if it was dropped."""
        if self._closed:
            return False
        if self.queued_bytes + len(frame) > self.byte_limit and self.queued_bytes:
            self._drop_warning()
            return False
        if self._write_now(frame, binary):
            return True
        entry = Entry(frame, binary, key)
        per = self._per_key.get(key)
        if per is None:
            per = self._per_key[key] = deque()
        per.append(entry)
        if queue_length > 0:
            while len(per) > queue_length:
                self._release(per.popleft())
                self.dropped += 1
        self._queue.append(entry)
        self.idle.clear()
        self.queued_bytes += entry.size
        if self.queued_bytes > self.peak_bytes:
            self.peak_bytes = self.queued_bytes
        self._wakeup.set()
        return True

    def _write_now(self, frame: bytes, binary: bool) -> bool:
        """Write at once, skipping the pump task, while nothing is queued or being written
        (under ``corked()``: when the cork comes out)."""
        if self._queue or (self._last_write is not None and not self._last_write.done()):
            return False
        if _corked is not None:
            if self._held is None:
                self._held = []
                _corked.append(self)
            self._held.append((frame, binary))
            return True
        try:
            self._last_write = self._write(frame, binary)
        except Exception:   # the connection went away; the handler cleans up
            self._closed = True
        return True

    def _uncork(self) -> None:
        frames, self._held = self._held, None
        if not frames or self._closed:
            return
        try:
            self._last_write = self._write(*frames[0]) if len(frames) == 1 else self._write_many(frames)
        except Exception:   # the connection went away; the handler cleans up
            self._closed = True

    def forget(self, key: object) -> None:
        """Drop everything still queued for a subscription that went away."""
        for entry in self._per_key.pop(key, ()):
            if entry.alive:
                self._release(entry)

    def _release(self, entry: Entry) -> None:
        """A queued entry dropped: its frame goes now, not when the pump reaches its place in
        the queue (a client that stopped reading never lets the pump get there: a newest-wins
        camera kept each dropped frame's megabyte in the queue). The queue is compacted once it
        is mostly such shells."""
        entry.alive = False
        entry.frame = b''
        self.queued_bytes -= entry.size
        self._dead += 1
        if self._dead > 64 and self._dead * 2 > len(self._queue):
            self._queue = deque(e for e in self._queue if e.alive)
            self._dead = 0

    def _drop_warning(self) -> None:
        self.dropped += 1
        self._dropped_since_warn += 1
        now = asyncio.get_running_loop().time()
        if self._on_overflow and now - self._last_warn >= self._warn_interval:
            self._last_warn = now
            count, self._dropped_since_warn = self._dropped_since_warn, 0
            self._on_overflow(count)

    async def _run(self) -> None:
        try:
            await self._pump()
        except asyncio.CancelledError:
            raise
        except Exception:   # the connection went away under us; the handler cleans up
            self._closed = True

    async def _pump(self) -> None:
        while not self._closed:
            queue = self._queue   # anew each time: _release may have compacted it
            if not queue:
                self.idle.set()
                self._wakeup.clear()
                await self._wakeup.wait()
                continue
            if self._last_write is not None and not self._last_write.done():
                await self._last_write   # a direct write still owns the socket
                continue
            batch = 0
            frames: Frames = []
            while queue and batch < BATCH_BYTES:
                entry = queue.popleft()
                if not entry.alive:
                    self._dead -= 1
                    continue
                entry.alive = False
                self.queued_bytes -= entry.size
                if entry.key is not None:
                    per = self._per_key.get(entry.key)
                    if per and per[0] is entry:
                        per.popleft()
                else:
                    self.reply_count -= 1
                    self.reply_bytes -= entry.size
                frames.append((entry.frame, entry.binary))
                batch += entry.size
            if frames:
                pending = self._last_write = self._write_many(frames)
                if pending is not None:
                    await pending   # flow control: wait until the socket took the batch


_corked: list[Outbox] | None = None   # outboxes holding frames while corked
_at_end: list[Callable[[], None]] = []   # run as the outermost cork ends, before its frames go out


class _Cork:
    """The outermost cork's block: ``_corked`` holds the outboxes whose frames wait for its end."""

    def __enter__(self) -> None:
        global _corked
        _corked = []

    def __exit__(self, *exc) -> None:
        global _corked
        held = _corked
        try:
            while _at_end:
                fn = _at_end.pop(0)
                try:
                    fn()
                except Exception:
                    log.exception('at the end of a batch: %s', getattr(fn, '__qualname__', fn))
        finally:
            _corked = None
            for box in held:
                box._uncork()


_OUTER, _INNER = _Cork(), contextlib.nullcontext()


def corked():
    """Frames that outboxes would write at once inside this block go out when it ends, one
    socket write per client: a batch of messages (the frames of one socket read, a batch from
    the backend) costs each client one send (and its reader one wake-up) instead of one per
    message. Nested blocks join the outer one. (Classes, not a generator: the gateway enters
    it about three times for every message it relays.)"""
    return _OUTER if _corked is None else _INNER


def after_batch(fn: Callable[[], None]) -> bool:
    """Run ``fn`` as the open cork ends, before its frames go out (the frames fn causes join
    them); False, and nothing done, when no cork is open."""
    if _corked is None:
        return False
    _at_end.append(fn)
    return True


# what a backend is started with (``Backend.start``, by ``server.serve``): a batch of messages it
# delivers is one cork, and what the gateway publishes meanwhile is taken at its end
BATCHING = {'batch_scope': corked, 'after_batch': after_batch}


def _malloc_trim():
    path = ctypes.util.find_library('c')
    try:
        return ctypes.CDLL(path).malloc_trim if path else None
    except (OSError, AttributeError):   # not glibc
        return None


_TRIM = _malloc_trim()


def release_memory() -> None:
    """Hand freed heap pages back to the system (glibc keeps them otherwise, so a burst of
    queued frames would stay in the process's RSS long after the client left)."""
    if _TRIM is not None:
        _TRIM(0)
