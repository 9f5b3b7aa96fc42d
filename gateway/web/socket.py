"""The rosbridge websocket: frames read and written with as few copies as the socket allows, each
message handed to its client's session (``bridge.session``), which answers through its outbox.

The handler speaks to its connection's protocol object alone (``self.ws_connection``: ``send``,
``send_many``, ``close``, ``selected_subprotocol``, frames in through ``on_message``): picows's
(``fastio.Connection``) for a plain connection when it is installed, tornado's own
(``TextAsBytesProtocol``) for TLS, permessage-deflate, unix sockets, ``--no-fast-io`` or
without picows."""

from __future__ import annotations

import asyncio
import socket
import struct

import tornado.iostream
import tornado.websocket

from ..bridge.gateway import Gateway
from ..bridge.foxglove.session import choose_subprotocol, session_for
from ..bridge.session import ClientSession
from .fastio import Connection, frame_header, frame_parts
from .pages import write_page

TORNADO_TESTED = 'tornado>=6.4,<6.7'   # the range pyproject.toml pins; its private parts are checked below
TEXT, BINARY, CLOSE = 0x1, 0x2, 0x8  # websocket opcodes
FLUSH_BEFORE_CLOSE = 1.0  # seconds a failing connection waits for its last status to go out
READ_CHUNK = 128 * 1024   # bytes a connection asks its socket for at once (more when a frame needs it)
# ?compression=deflate on the websocket URL: permessage-deflate (RFC 7692) for this connection alone,
# at zlib's fastest level. The class view asks for it: its marker JSON shrinks about tenfold over a
# home line, and deflate costs CPU for that one connection rather than for every student's.
DEFLATE = {'compression_level': 1}

# Bytes the kernel may hold for a client beyond what is in flight. Linux's send buffer grows to
# megabytes for a connection that reads slowly: a 1 Mbit/s client had ~400 KiB (3+ s of camera
# frames) waiting there, out of reach of the outbox's newest-wins. With TCP_NOTSENT_LOWAT the
# socket takes more only once its unsent bytes fall below this, so frames wait in the outbox,
# where a newer one replaces them; what is in flight (the link's own queue) is left to TCP.
NOTSENT_LOWAT = 16 * 1024
TCP_NOTSENT_LOWAT = getattr(socket, 'TCP_NOTSENT_LOWAT', 25)   # Linux's number, if Python lacks the name


class TextAsBytesProtocol(tornado.websocket.WebSocketProtocol13):
    """Hands a text message to the handler undecoded, flagged as text (``handler.text_frame``).

    Tornado decodes text messages itself and drops the connection without a close frame when
    one is not valid UTF-8, before any of our code runs. Here a text message goes through
    tornado's binary path (decompression and accounting unchanged) and the handler decodes it,
    once, so invalid UTF-8 can get a status and a 1007 close (RFC 6455, section 8.1).
    A close frame whose reason is not UTF-8 (tornado raises decoding it, and the connection
    ends without an answer) is echoed with its code alone, as tornado echoes every close.
    """

    _rview: memoryview | None = None   # bytes read from the socket and not yet taken, in _rview[_rstart:_rend]
    _rstart = _rend = 0

    async def _read_bytes(self, n: int) -> bytes:
        """The next n bytes of the connection. Tornado reads each frame's header, length, mask
        and payload with a read of its own and copies every payload twice before unmasking it;
        here one read takes all the socket holds (many small frames, or one large frame), into
        a buffer that is let go once its bytes are taken."""
        if not n:
            return b''
        if self._rend - self._rstart < n:
            await self._fill(n)
        start = self._rstart
        data = bytes(self._rview[start:start + n])
        self._rstart = start + n
        if self._rstart == self._rend:
            self._rview, self._rstart, self._rend = None, 0, 0
        self._wire_bytes_in += n
        return data

    async def _fill(self, n: int) -> None:
        old, start, end = self._rview, self._rstart, self._rend
        # a read may not pass the stream's max_buffer_size (the hard frame limit): tornado
        # closes the connection when it does
        view = memoryview(bytearray(max(n, min(READ_CHUNK, self.stream.max_buffer_size // 2))))
        if old is not None:
            view[:end - start] = old[start:end]
        self._rview, self._rstart, self._rend = view, 0, end - start
        while self._rend < n:
            self._rend += await self.stream.read_into(view[self._rend:], partial=True)

    @property
    def socket(self):
        return self.stream.socket if self.stream is not None else None

    def send(self, payload: bytes, binary: bool):
        """One message: its frame header and payload go to the socket as they are (tornado's
        write_message copies them into one frame and wraps each write in a task)."""
        stream = self._plain_stream()
        if stream is None:
            return self.handler.write_message(payload, binary=binary)
        return _write(stream, [frame_header(len(payload), binary), payload])

    def send_many(self, frames: list[tuple[bytes, bool]]):
        """Several messages in one write to the socket (one send, one wake-up of the reader)."""
        stream = self._plain_stream()
        if stream is None:
            last = None
            for payload, binary in frames:
                last = self.handler.write_message(payload, binary=binary)
            return last
        return _write(stream, frame_parts(frames))

    def _plain_stream(self):
        """The connection's stream when frames may be written to it as the gateway builds them
        (no compression, open); else None, and tornado's write_message builds each frame."""
        if self.is_closing() or self.handler.deflates():
            return None
        return self.stream

    def _handle_message(self, opcode: int, data: bytes):
        if opcode != TEXT:
            if opcode == CLOSE and len(data) > 2 and not _is_utf8(data[2:]):
                data = data[:2]
            return super()._handle_message(opcode, data)
        self.handler.text_frame = True
        try:
            return super()._handle_message(BINARY, data)
        finally:
            self.handler.text_frame = False


def check_tornado(protocol: type = tornado.websocket.WebSocketProtocol13) -> None:
    """TextAsBytesProtocol overrides two private methods of tornado's websocket protocol, which
    its frame loop (``_receive_frame``) calls, and keeps tornado's byte count (``_wire_bytes_in``).
    A tornado release that renames any of them would leave the override silently unused (text
    frames decoded by tornado again, invalid UTF-8 dropping the connection without a close), so
    the gateway refuses to start instead, naming what is missing (RuntimeError)."""
    loop = getattr(protocol, '_receive_frame', None)
    calls = set(getattr(getattr(loop, '__code__', None), 'co_names', ()))
    reads = getattr(protocol, '_read_bytes', None)
    counts = set(getattr(getattr(reads, '__code__', None), 'co_names', ()))
    missing = [what for what, ok in (
        (f'{protocol.__name__}._receive_frame', callable(loop)),
        (f'{protocol.__name__}._read_bytes, called by _receive_frame', callable(reads) and '_read_bytes' in calls),
        (f'{protocol.__name__}._handle_message, called by _receive_frame',
         callable(getattr(protocol, '_handle_message', None)) and '_handle_message' in calls),
        (f'{protocol.__name__}._wire_bytes_in, counted by _read_bytes', '_wire_bytes_in' in counts),
    ) if not ok]
    if missing:
        raise RuntimeError(f'rosgate\'s websocket reads frames through private parts of tornado that tornado '
                           f'{tornado.version} does not have: {"; ".join(missing)}. Install the tested '
                           f'tornado: pip install \'{TORNADO_TESTED}\'')


check_tornado()


def _is_utf8(data: bytes) -> bool:
    try:
        data.decode('utf-8')
    except UnicodeDecodeError:
        return False
    return True


class RosbridgeHandler(tornado.websocket.WebSocketHandler):
    """Websocket upgrade on the rosbridge path; a plain GET there serves the IDE."""

    def initialize(self, gateway: Gateway) -> None:
        self.gateway = gateway
        self.session: ClientSession | None = None
        self.text_frame = False   # set by TextAsBytesProtocol while it delivers a text message
        self.auth_deadline: asyncio.TimerHandle | None = None
        self._deflate: bool | None = None

    async def get(self, *args, **kwargs) -> None:
        if self.request.headers.get('Upgrade', '').lower() != 'websocket':
            write_page(self, self.gateway.settings.ide_dir / 'index.html', isolated=True)
            return
        await super().get(*args, **kwargs)

    def get_websocket_protocol(self):
        if (self.gateway.settings.fast_io and self.request.headers.get('Sec-WebSocket-Version') == '13'
                and Connection.carries(self)):
            return Connection(self)
        protocol = super().get_websocket_protocol()
        if type(protocol) is tornado.websocket.WebSocketProtocol13:
            protocol.__class__ = TextAsBytesProtocol   # same state, one method more
        return protocol

    def select_subprotocol(self, subprotocols: list[str]) -> str | None:
        """Foxglove's protocol for a client that offers it (Foxglove, Lichtblick); rosbridge's otherwise."""
        return choose_subprotocol(subprotocols)

    def check_origin(self, origin: str) -> bool:
        """As for the HTTP routes (``api.check_origin``): a browser's own Sec-Fetch-Site of
        same-origin passes (behind a TLS proxy the page's https origin differs from what the gateway
        sees unless the proxy is trusted); otherwise the Origin must be ours or allowed."""
        if self.request.headers.get('Sec-Fetch-Site', '').lower() == 'same-origin':
            return True
        return self.gateway.policy.origin_allowed(origin, self.request)

    def deflates(self) -> bool:
        """Whether this connection offers permessage-deflate: --use-compression, or the client
        asked with ?compression=deflate."""
        if self._deflate is None:
            self._deflate = (self.gateway.settings.use_compression
                             or self.get_query_argument('compression', '') == 'deflate')
        return self._deflate

    def get_compression_options(self):
        if self.gateway.settings.use_compression:
            return {}
        return DEFLATE if self.deflates() else None

    def open(self, *args, **kwargs) -> None:
        self.set_nodelay(True)   # without it Nagle's algorithm stalls small messages
        bound_unsent(self.ws_connection)
        self.session = session_for(self.selected_subprotocol, self.gateway, self._send, self._send_many, self.close,
                                   self.request.remote_ip or '', ping=self.ping)
        self.session.attrs.update(self.gateway.policy.connect_attrs(self.request))
        self.session.open()
        self.gateway.hooks.connect(self.session, self.request)   # e.g. a robot-side run knowing its own connection
        self.gateway.count_clients()
        timeout = self.gateway.settings.auth_timeout
        if not self.gateway.policy.signed_in(self.session) and timeout > 0:
            self.auth_deadline = asyncio.get_running_loop().call_later(timeout, self._auth_deadline, timeout)

    def _auth_deadline(self, timeout: float) -> None:
        """Under --auth a connection that has not authenticated in time is closed (1008), after a
        status saying why: an idle unauthenticated socket holds memory and a file for nothing."""
        self.auth_deadline = None
        session = self.session
        if session is None or session.closed or session.closing or 'role' in session.attrs:
            return
        session.status('error', f'not authenticated within {timeout:g} s; closing the connection (1008)')
        asyncio.ensure_future(session.hang_up(1008, 'not authenticated in time', FLUSH_BEFORE_CLOSE))

    def _send(self, payload: bytes, binary: bool):
        connection = self.ws_connection
        if connection is None:
            raise tornado.websocket.WebSocketClosedError()
        return connection.send(payload, binary)

    def _send_many(self, frames: list[tuple[bytes, bool]]):
        connection = self.ws_connection
        if connection is None:
            raise tornado.websocket.WebSocketClosedError()
        return connection.send_many(frames)

    def on_message(self, message: str | bytes):
        if self.session is None or self.session.closing:
            return None
        text = self.text_frame
        if text and not message.isascii():   # ASCII is UTF-8: the JSON parser reads those bytes as they are
            try:
                message = message.decode('utf-8')
            except UnicodeDecodeError as e:   # keep only words: e.object is the whole frame
                problem = f'byte 0x{message[e.start:e.start + 1].hex()} at offset {e.start}: {e.reason}'
                return self._invalid_text(problem)
        self.session.receive(message, text)
        return None

    async def _invalid_text(self, problem: str) -> None:
        """A text message that is not UTF-8 fails the connection (RFC 6455: close 1007). The
        client is told why first; tornado reads no further frame while this runs."""
        self.session.status('error', f'text frame is not valid UTF-8 ({problem}); closing the connection (1007)')
        await self.session.hang_up(1007, 'text frame is not valid UTF-8', FLUSH_BEFORE_CLOSE)

    def on_pong(self, data: bytes) -> None:
        if self.session is not None:
            self.session.fence.pong(data)

    def on_close(self) -> None:
        if self.auth_deadline is not None:
            self.auth_deadline.cancel()
            self.auth_deadline = None
        if self.session is not None:
            self.session.close()
            self.gateway.count_clients()


def bound_unsent(stream, limit: int = NOTSENT_LOWAT) -> None:
    """Keep the kernel's unsent share of a connection small (NOTSENT_LOWAT); ``stream`` is
    anything with a ``socket`` (a tornado stream, a websocket connection). One without a TCP socket
    (a test's pipe, a platform without the option) is left as it is."""
    sock = getattr(stream, 'socket', None)
    if sock is None or sock.family not in (socket.AF_INET, socket.AF_INET6):
        return
    try:
        sock.setsockopt(socket.IPPROTO_TCP, TCP_NOTSENT_LOWAT, limit)
    except OSError:
        pass


MAX_PARTS = 512    # parts of one sendmsg (Linux allows 1024)


def _write(stream, parts: list) -> object:
    """Write the parts in order. While the stream has nothing queued they go to the socket in
    one sendmsg, without joining them (a 64 KiB message is not copied to put a header before
    it); what the socket does not take now, or everything when tornado is still writing or the
    stream is TLS, goes through the stream's buffer. Returns the stream's future, or None when
    the socket took it all."""
    if (type(stream) is tornado.iostream.IOStream and not stream.writing()
            and len(parts) <= MAX_PARTS):
        try:
            sent = stream.socket.sendmsg(parts)
        except OSError:   # the socket is full, or gone (tornado's write below finds out and closes)
            sent = 0
        if sent:
            for i, part in enumerate(parts):
                if sent < len(part):
                    parts = [memoryview(part)[sent:], *parts[i + 1:]]
                    break
                sent -= len(part)
            else:
                return None
    return stream.write(b''.join(parts))

