"""Compiled I/O where it is installed: the websocket's frames through picows (a compiled websocket
core) once tornado has done the HTTP, and uvloop under tornado's asyncio loop (``loop_factory``).

Measured on the 2-core machine (std_msgs/String of 64 B, 32 in flight, one publisher and one
subscriber connection): tornado's frame loop (a coroutine and four awaits per frame) and one socket
write per message delivered took about half of the gateway's time on either backend, the protocol
work (parse, rules, publish, encode) the rest; a bare relay of the same frames cost 44 µs a message
on tornado and 12.5 µs on picows (docs/benchmarks.md).

tornado keeps everything before the first frame: it routes the upgrade request and the handler
runs every check on it (the Host and Origin checks, cookies and tokens at ``open``, the subprotocol,
whether permessage-deflate is negotiated). For a connection that picows can carry (plain TCP, no
TLS and no deflate: ``Connection.carries``) the handler's ``get_websocket_protocol`` returns a
``Connection`` instead of tornado's protocol. It plays tornado's ``WebSocketProtocol`` role toward
the handler (``accept_connection``, ``write_message``, ``write_ping``, ``close``, ``is_closing``,
``selected_subprotocol``) and adds the gateway's ``send`` and ``send_many``: the handler and its
session do not know which one carries them. ``accept_connection`` takes the socket from tornado
(``RequestHandler.detach``), hands it to an asyncio transport with picows's protocol on it, and
replays the handshake to it, so picows answers 101 to the same key (with the chosen subprotocol)
and reads and writes every frame from then on.

What the gateway promised over tornado holds here too: a text message reaches the handler as
bytes flagged as text (the handler checks UTF-8 and answers 1007); messages in several frames are
joined, and one past the hard size limit closes the connection with 1009, as does a single frame
past it (picows); a client's close is echoed with its code; the keepalive ping goes out every
``--websocket-ping-interval`` whatever the client sends (a proxy such as nginx times out on what the
gateway sends: a client that only publishes still gets them) and closes a connection whose peer does
not answer within ``--websocket-ping-timeout``; a write the socket does not take at once returns a future that completes once the
transport's buffer is empty (the outbox's flow control); an ``on_message`` that returns an
awaitable holds the connection's later frames until it is done, as tornado does.

The frames of one read are handled in a row inside the outboxes' cork (``bridge.outbox.corked``):
every client gets what they produced in one socket write, not one write per message.

Without picows (no wheel for the platform, or a release outside the tested range) or with
``--no-fast-io`` every connection stays on tornado's protocol (``socket.TextAsBytesProtocol``),
and without uvloop (or with ``--no-fast-io``) tornado runs on asyncio's own loop.
"""

from __future__ import annotations

import asyncio
import logging
import socket
import ssl
import struct
import sys
from collections import deque

import tornado.iostream
import tornado.websocket

from ..bridge.outbox import corked

try:
    import picows
    from picows import WSListener, WSMsgType, WSUpgradeResponse, WSUpgradeResponseWithListener
    from picows.picows import WSProtocol   # what ws_create_server puts on each accepted connection
except ImportError:   # no wheel for this platform: tornado carries every connection
    picows = None
    WSListener = WSProtocol = object
try:
    import uvloop
except ImportError:
    uvloop = None
try:
    import aiofastnet   # picows's own transports (a picows requirement); the loop's otherwise
except ImportError:
    aiofastnet = None

PICOWS_TESTED = 'picows>=2.3.1,<2.4'   # WSProtocol's constructor is not public API: the range pyproject pins
log = logging.getLogger('rosgate.websocket')
# picows logs every connection at INFO and each client's protocol error at ERROR (a log line per
# hostile client); tornado says such things at DEBUG. Our callbacks log their own failures.
picows_log = logging.getLogger('rosgate.websocket.picows')
picows_log.setLevel(logging.CRITICAL)
CLOSE_WAIT = 5.0   # s the client has to answer our close frame (tornado's wait) before the socket goes
KEEPALIVE = b'rosgate-keepalive'   # the payload of picows's idle pings, told apart from the session's own
HANDSHAKE_KEY = 'Sec-WebSocket-Key'
MESSAGE, PONG, CLOSE, FAIL = range(4)   # what _pending holds, in the order it was read


def _tested(version: str) -> bool:
    """Whether a picows release is in PICOWS_TESTED (2.3.1 up to 2.4)."""
    try:
        release = tuple(int(v) for v in version.split('.')[:3])
    except ValueError:
        return False
    return (2, 3, 1) <= release < (2, 4)


def loop_factory(fast: bool):
    """The event loop the gateway runs on (``asyncio.Runner``'s loop_factory): uvloop's when asked
    and installed, else None (asyncio's own)."""
    return uvloop.new_event_loop if fast and uvloop is not None else None


def available() -> bool:
    """Whether picows is installed in the tested range."""
    return picows is not None and _tested(getattr(picows, '__version__', ''))


class Connection:
    """One websocket connection carried by picows; tornado's WebSocketProtocol toward the handler."""

    def __init__(self, handler: tornado.websocket.WebSocketHandler):
        self.handler = handler
        self.selected_subprotocol: str | None = None
        self.socket: socket.socket | None = None     # for socket options (socket.bound_unsent)
        self.transport = None                        # picows's WSTransport, once upgraded
        self._underlying = None                      # its asyncio transport
        self._closing = False                        # a close frame went out (or the socket is gone)
        self._gone = False
        self._close_timer: asyncio.TimerHandle | None = None
        self._paused = False                          # the transport holds unsent bytes
        self._drained: asyncio.Future | None = None
        self._parts: list[bytes] | None = None        # a message arriving in several frames
        self._parts_text = False
        self._parts_size = 0
        self._pending: deque = deque()                # (MESSAGE, payload, text), (PONG, data, _), ... in order
        self._failed = False                          # a protocol error ended the frames we take
        self._holding: asyncio.Future | None = None   # an on_message still running: later frames wait

    @staticmethod
    def carries(handler: tornado.websocket.WebSocketHandler) -> bool:
        """Whether picows can carry this upgrade request's connection: plain TCP (TLS and unix
        sockets stay with tornado) and no permessage-deflate to negotiate (picows has none)."""
        if not available():
            return False
        stream = getattr(handler.request.connection, 'stream', None)
        if type(stream) is not tornado.iostream.IOStream:   # SSLIOStream, or no stream
            return False
        sock = getattr(stream, 'socket', None)
        if sock is None or isinstance(sock, ssl.SSLSocket) or sock.family not in (socket.AF_INET, socket.AF_INET6):
            return False
        offered = handler.request.headers.get('Sec-WebSocket-Extensions', '')
        return not ('permessage-deflate' in offered and handler.get_compression_options() is not None)

    # --- the handshake ------------------------------------------------------------------------

    async def accept_connection(self, handler: tornado.websocket.WebSocketHandler) -> None:
        headers = handler.request.headers
        if not all(headers.get(f) for f in ('Host', HANDSHAKE_KEY, 'Sec-Websocket-Version')):
            handler.set_status(400)
            handler.finish('Missing/Invalid WebSocket headers')
            return
        offered = [s.strip() for s in headers.get('Sec-WebSocket-Protocol', '').split(',') if s.strip()]
        self.selected_subprotocol = handler.select_subprotocol(offered)
        if self.selected_subprotocol is not None and self.selected_subprotocol not in offered:
            raise ValueError(f'select_subprotocol chose {self.selected_subprotocol!r}, not offered')
        stream = handler.detach()
        sock, early = _take_socket(stream)
        request = (f'GET / HTTP/1.1\r\nHost: {headers["Host"]}\r\nUpgrade: websocket\r\n'
                   f'Connection: Upgrade\r\n{HANDSHAKE_KEY}: {headers[HANDSHAKE_KEY]}\r\n'
                   'Sec-WebSocket-Version: 13\r\n\r\n').encode('latin-1') + early
        interval = handler.ping_interval or 0
        timeout = min(handler.ping_timeout or interval, interval)
        max_size = handler.max_message_size
        loop = asyncio.get_running_loop()

        def protocol() -> _Protocol:
            return _Protocol(request, self._listener, max_size, interval, timeout)

        try:
            if aiofastnet is not None:
                await aiofastnet.connect_accepted_socket(loop, protocol, sock)
            else:
                await loop.connect_accepted_socket(protocol, sock)
        except OSError:   # the client went away during the handover
            sock.close()
            self._gone = self._closing = True
            handler.on_ws_connection_close()

    def _listener(self, request) -> WSUpgradeResponseWithListener:
        extra = {'Sec-WebSocket-Protocol': self.selected_subprotocol} if self.selected_subprotocol else None
        return WSUpgradeResponseWithListener(WSUpgradeResponse.create_101_response(extra), _Listener(self))

    def _connected(self, transport) -> None:
        self.transport = transport
        self._underlying = transport.underlying_transport
        # pause_writing as soon as anything waits in the transport, resume once it is all sent
        self._underlying.set_write_buffer_limits(high=0)
        self.socket = self._underlying.get_extra_info('socket')
        handler = self.handler
        self._run(handler.open, *handler.open_args, **handler.open_kwargs)

    # --- frames in ----------------------------------------------------------------------------

    def _frame(self, frame) -> None:
        """One frame from picows, into ``_pending`` in order: a message (joined from its frames),
        a pong, the client's close, or the protocol error that ends the connection there."""
        kind = frame.msg_type
        if kind is WSMsgType.CLOSE:   # picows checked its code and its reason's UTF-8
            self._pending.append((CLOSE, frame.get_payload_as_bytes(), False))
            return
        if self._failed:
            return
        if kind is WSMsgType.PONG:
            self._pending.append((PONG, frame.get_payload_as_bytes(), False))
            return
        if kind is not WSMsgType.TEXT and kind is not WSMsgType.BINARY and kind is not WSMsgType.CONTINUATION:
            return   # a ping: picows answered it
        if frame.rsv1 or frame.rsv2 or frame.rsv3:   # no extension was negotiated
            return self._fail(1002, 'reserved bits set')
        payload = frame.get_payload_as_bytes()
        if kind is WSMsgType.CONTINUATION:
            if self._parts is None:
                return self._fail(1002, 'continuation frame without a message')
            self._parts_size += len(payload)
            if self._parts_size > self.handler.max_message_size:
                return self._fail(1009, 'message too big')
            self._parts.append(payload)
            if not frame.fin:
                return None
            payload, text = b''.join(self._parts), self._parts_text
            self._parts = None
        else:
            if self._parts is not None:
                return self._fail(1002, 'a new message inside a fragmented one')
            text = kind is WSMsgType.TEXT
            if not frame.fin:
                self._parts, self._parts_text, self._parts_size = [payload], text, len(payload)
                return None
        self._pending.append((MESSAGE, payload, text))
        return None

    def _fail(self, code: int, reason: str) -> None:
        """A protocol error: what came before it is handled, then the connection closes with code."""
        self._failed = True
        self._parts = None
        self._pending.append((FAIL, code, reason))

    def _deliver(self) -> None:
        """Hand what was read so far to the handler, in order, inside one cork: the frames it
        causes go out in one write per client when the last one is handled. Messages after the
        connection began to close are not handled (tornado's handler would drop them too)."""
        pending, handler = self._pending, self.handler
        ending = None
        with corked():
            while pending and self._holding is None and not self._gone:
                kind, payload, text = pending.popleft()
                if kind is MESSAGE:
                    if self._closing:
                        continue
                    handler.text_frame = text
                    try:
                        self._run(handler.on_message, payload)
                    finally:
                        handler.text_frame = False
                elif kind is PONG:
                    self._run(handler.on_pong, payload)
                else:   # the end: after the frames the messages before it caused went out
                    ending = kind, payload, text
                    break
        if ending is None or self._gone:
            return
        kind, payload, text = ending
        if kind is CLOSE:
            self._client_closed(payload)
        else:
            self.close(payload, text)
            self._abort()

    def _run(self, callback, *args, **kwargs) -> None:
        """A handler callback, as tornado runs it: an exception aborts the connection; an
        awaitable holds the later frames until it is done."""
        try:
            result = callback(*args, **kwargs)
        except Exception:
            self.handler.log_exception(*sys.exc_info())
            self._abort()
            return
        if result is None:
            return
        self._holding = asyncio.ensure_future(result)
        if self._underlying is not None:
            self._underlying.pause_reading()
        self._holding.add_done_callback(self._held_done)

    def _held_done(self, future: asyncio.Future) -> None:
        self._holding = None
        if not future.cancelled() and future.exception() is not None:
            exc = future.exception()
            self.handler.log_exception(type(exc), exc, exc.__traceback__)
            self._abort()
            return
        if self._gone:
            return
        self._underlying.resume_reading()
        self._deliver()

    def _client_closed(self, payload: bytes) -> None:
        code = None
        if len(payload) >= 2:
            code = struct.unpack('!H', payload[:2])[0]
            self.handler.close_code = code
            self.handler.close_reason = payload[2:].decode('utf-8', 'replace')
        if not self._closing:   # the client began: echo its code, as tornado does
            self._send_close(code, None)
        self._abort()

    # --- frames out (tornado's names, then the gateway's) -------------------------------------

    def write_message(self, message: str | bytes, binary: bool = False) -> asyncio.Future:
        if isinstance(message, str):
            message = message.encode('utf-8')
        pending = self.send(message, binary)
        if pending is None:
            pending = asyncio.get_running_loop().create_future()
            pending.set_result(None)
        return pending

    def send(self, payload: bytes, binary: bool) -> asyncio.Future | None:
        """One message; None when the socket took it all, else a future done once it has."""
        if self._closing:
            raise tornado.websocket.WebSocketClosedError()
        self.transport.send(WSMsgType.BINARY if binary else WSMsgType.TEXT, payload)
        return self._drain_future() if self._paused else None

    def send_many(self, frames: list[tuple[bytes, bool]]) -> asyncio.Future | None:
        """Several messages in one write to the transport (one system call while it is empty)."""
        if self._closing:
            raise tornado.websocket.WebSocketClosedError()
        self._underlying.writelines(frame_parts(frames))
        return self._drain_future() if self._paused else None

    def write_ping(self, data: bytes) -> None:
        if not self._closing:
            self.transport.send_ping(data)

    def set_nodelay(self, value: bool) -> None:
        if self.socket is not None:
            self.socket.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1 if value else 0)

    def is_closing(self) -> bool:
        return self._closing

    def close(self, code: int | None = None, reason: str | None = None) -> None:
        """Send a close frame; the socket goes when the client answers, or after CLOSE_WAIT."""
        if self._closing:
            return
        if code is None and reason is not None:
            code = 1000
        self._send_close(code, reason)
        self._close_timer = asyncio.get_running_loop().call_later(CLOSE_WAIT, self._abort)

    def _send_close(self, code: int | None, reason: str | None) -> None:
        self._closing = True
        if self.transport is None or self._gone:
            return
        payload = b'' if code is None else struct.pack('!H', code) + (reason or '').encode('utf-8')[:123]
        self.transport.send(WSMsgType.CLOSE, payload)

    def _abort(self) -> None:
        self._closing = True
        if self.transport is not None and not self._gone:
            self.transport.disconnect()

    def on_connection_close(self) -> None:   # the handler's on_connection_close calls this
        self._abort()

    def _disconnected(self) -> None:
        self._gone = self._closing = True
        self._pending.clear()
        if self._close_timer is not None:
            self._close_timer.cancel()
            self._close_timer = None
        self._resume()
        self.handler.on_ws_connection_close(self.handler.close_code, self.handler.close_reason)

    # --- flow control -------------------------------------------------------------------------

    def _drain_future(self) -> asyncio.Future:
        if self._drained is None:
            self._drained = asyncio.get_running_loop().create_future()
        return self._drained

    def _pause(self) -> None:
        self._paused = True

    def _resume(self) -> None:
        self._paused = False
        drained, self._drained = self._drained, None
        if drained is not None and not drained.done():
            drained.set_result(None)


class _Listener(WSListener):
    """picows's callbacks, handed to the Connection."""

    def __init__(self, connection: Connection):
        self.connection = connection

    def on_ws_connected(self, transport) -> None:
        self.connection._connected(transport)

    def on_ws_frame(self, transport, frame) -> None:
        connection = self.connection
        try:
            connection._frame(frame)
            if frame.last_in_buffer:
                connection._deliver()
        except Exception:   # a bug of ours: said in our log (picows's says nothing), the connection ends
            log.exception('websocket frame from %s', connection.handler.request.remote_ip)
            connection._abort()

    def on_ws_disconnected(self, transport) -> None:
        self.connection._disconnected()

    def pause_writing(self) -> None:
        self.connection._pause()

    def resume_writing(self) -> None:
        self.connection._resume()

    def send_user_specific_ping(self, transport) -> None:
        transport.send_ping(KEEPALIVE)

    def is_user_specific_pong(self, frame) -> bool:
        return frame.msg_type == WSMsgType.PONG and frame.get_payload_as_bytes() == KEEPALIVE


class _Protocol(WSProtocol):
    """picows's server protocol, given the upgrade request tornado read as soon as it is on the
    socket (before anything more can be read from it)."""

    def __init__(self, request: bytes, listener_factory, max_size: int, ping_interval: float, ping_timeout: float):
        super().__init__(None, None, False, listener_factory, picows_log, True, None,
                         ping_interval > 0, ping_interval or 20.0, ping_timeout or 20.0,
                         picows.WSAutoPingStrategy.PING_PERIODICALLY, True, max_size, None, 16 * 1024)
        self._request = request

    def connection_made(self, transport) -> None:
        super().connection_made(transport)
        request, self._request = self._request, b''
        while request:
            buffer = self.get_buffer(len(request))
            n = min(len(buffer), len(request))
            buffer[:n] = request[:n]
            request = request[n:]
            self.buffer_updated(n)


def _take_socket(stream: tornado.iostream.IOStream) -> tuple[socket.socket, bytes]:
    """The connection's socket out of tornado's hands (a duplicate; tornado closes its own), and
    any bytes tornado read past the request (a client may not send frames before the 101; if one
    did, they are not lost)."""
    size = getattr(stream, '_read_buffer_size', 0)
    early = bytes(stream._read_buffer[:size]) if size else b''
    sock = stream.socket.dup()
    stream.close()
    sock.setblocking(False)
    return sock, early


SMALL = 2048       # payloads below this are copied together with their header into one part


def frame_parts(frames: list[tuple[bytes, bool]]) -> list:
    """The frames of several messages as one list of buffers for a single write: small frames
    joined, each large payload a part of its own after its header (not copied)."""
    parts: list = []
    small = bytearray()
    for payload, binary in frames:
        small += frame_header(len(payload), binary)
        if len(payload) < SMALL:
            small += payload
        else:
            parts.append(small)
            parts.append(payload)
            small = bytearray()
    if small:
        parts.append(small)
    return parts


def frame_header(size: int, binary: bool) -> bytes:
    """A final, unmasked frame's header (RFC 6455 5.2), as a server sends it."""
    first = 0x82 if binary else 0x81
    if size < 126:
        return bytes((first, size))
    if size <= 0xFFFF:
        return struct.pack('!BBH', first, 126, size)
    return struct.pack('!BBQ', first, 127, size)

