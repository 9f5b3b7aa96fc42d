"""Ceiling server: a bare tornado websocket server with no protocol work.

It routes `publish` frames to the subscribers of their topic by forwarding the
received frame as is (JSON subscribers) or a frame preloaded by the harness
(cbor / cbor-raw subscribers), and answers `call_service` with a preloaded reply
into which only the call's id is spliced. Control ops (subscribe, preload) are
parsed; the per-message path only finds the topic or id in the first bytes.
What it measures is the cost of tornado, the sockets and the clients: the
physical limit of this stack on this machine.

    python -m tests.bench.ceiling --port 0
prints `ceiling: websocket ws://127.0.0.1:PORT/` once started.
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import ctypes
import signal

import orjson
from tornado import httpserver, web, websocket
from tornado.netutil import bind_sockets

# A client whose unsent frames exceed this many bytes loses new topic frames
# (replies are never dropped), so a stalled reader cannot grow the server
# without bound; the default is rosgate's --send-buffer-limit.
SEND_BUFFER_LIMIT = 16 * 2**20


class Hub:
    """Routing state shared by all connections."""

    def __init__(self, send_buffer_limit: int = SEND_BUFFER_LIMIT) -> None:
        self.send_buffer_limit = send_buffer_limit
        self.subscribers: dict[str, dict[CeilingHandler, str]] = {}
        self.frames: dict[tuple[str, str], bytes] = {}
        self.replies: dict[str, tuple[str, str]] = {}


def _field(message: str, key: str) -> str | None:
    """The string value of `"key":"..."` near the start of a compact JSON frame."""
    start = message.find(key, 0, 256)
    if start < 0:
        return None
    start += len(key)
    end = message.find('"', start)
    return message[start:end] if end > 0 else None


class CeilingHandler(websocket.WebSocketHandler):
    def initialize(self, hub: Hub) -> None:
        self.hub = hub
        self.pending_bytes = 0
        self.dropped = 0
        self.topics: set[str] = set()

    def check_origin(self, origin: str) -> bool:
        return True

    def open(self) -> None:
        self.set_nodelay(True)

    def on_close(self) -> None:
        for topic in self.topics:
            self.hub.subscribers.get(topic, {}).pop(self, None)

    def on_message(self, message: str | bytes) -> None:
        if isinstance(message, bytes):
            return
        if message.startswith('{"op":"publish"'):
            topic = _field(message, '"topic":"')
            subs = self.hub.subscribers.get(topic) if topic else None
            if not subs:
                return
            frames = self.hub.frames
            for handler, compression in list(subs.items()):
                if compression == "none":
                    handler.send(message, False, droppable=True)
                else:
                    frame = frames.get((topic, compression))
                    if frame is None:
                        handler.send(message, False, droppable=True)
                    else:
                        handler.send(frame, True, droppable=True)
        elif message.startswith('{"op":"call_service"'):
            call_id = _field(message, '"id":"') or ""
            reply = self.hub.replies.get(_field(message, '"service":"') or "")
            if reply is not None:
                self.send(reply[0] + call_id + reply[1], False, droppable=False)
        else:
            self.control(orjson.loads(message))

    def control(self, op: dict) -> None:
        kind = op.get("op")
        if kind == "subscribe":
            topic = op["topic"]
            compression = op.get("compression") or "none"
            self.hub.subscribers.setdefault(topic, {})[self] = compression
            self.topics.add(topic)
        elif kind == "unsubscribe":
            self.hub.subscribers.get(op["topic"], {}).pop(self, None)
            self.topics.discard(op["topic"])
        elif kind == "ceiling_preload":
            if "service" in op:
                service = op["service"]
                head = orjson.dumps(
                    {"op": "service_response", "service": service,
                     "values": op["values"], "result": True}
                ).decode()[:-1]
                self.hub.replies[service] = (head + ',"id":"', '"}')
            else:
                frame = base64.b64decode(op["frame"])
                self.hub.frames[(op["topic"], op["compression"])] = frame
        # advertise, unadvertise and anything else need no work here

    def send(self, frame: str | bytes, binary: bool, droppable: bool) -> None:
        if droppable and self.pending_bytes > self.hub.send_buffer_limit:
            self.dropped += 1
            return
        try:
            future = self.write_message(frame, binary=binary)
        except websocket.WebSocketClosedError:
            return
        size = len(frame)
        self.pending_bytes += size
        future.add_done_callback(lambda _f: self._sent(size))

    def _sent(self, size: int) -> None:
        self.pending_bytes -= size


def tune_malloc() -> bool:
    """Keep large frames on the heap instead of a fresh mmap (and page faults) per frame.

    glibc serves allocations above its mmap threshold (dynamic, from 128 KiB) with
    mmap and trims the heap top eagerly; with frames of 100 KiB and more each copy
    then pays page faults. Raising both thresholds makes the copies plain memcpy.
    """
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3
    return bool(libc.mallopt(m_mmap_threshold, 32 * 2**20)) and \
        bool(libc.mallopt(m_trim_threshold, 128 * 2**20))


def make_app(hub: Hub | None = None) -> web.Application:
    return web.Application(
        [(r"/", CeilingHandler, {"hub": hub or Hub()})],
        websocket_max_message_size=64 * 1024 * 1024,
    )


async def serve(address: str, port: int, send_buffer_limit: int) -> None:
    sockets = bind_sockets(port, address)
    server = httpserver.HTTPServer(make_app(Hub(send_buffer_limit)))
    server.add_sockets(sockets)
    host, bound = sockets[0].getsockname()[:2]
    print(f"ceiling: websocket ws://{host}:{bound}/", flush=True)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    await stop.wait()
    server.stop()


def main() -> None:
    parser = argparse.ArgumentParser(prog="python -m tests.bench.ceiling")
    parser.add_argument("--address", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=0)
    parser.add_argument("--send-buffer-limit", type=int, default=SEND_BUFFER_LIMIT,
                        help="bytes queued per client before its topic frames are dropped")
    parser.add_argument("--no-malloc-tune", action="store_true",
                        help="leave glibc's malloc thresholds at their defaults")
    args = parser.parse_args()
    if not args.no_malloc_tune:
        tune_malloc()
    asyncio.run(serve(args.address, args.port, args.send_buffer_limit))


if __name__ == "__main__":
    main()
