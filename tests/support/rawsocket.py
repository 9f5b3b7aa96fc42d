"""A websocket client's first steps on a plain socket, written by hand: for what a client library
will not send (a close reason that is not UTF-8, a client that never reads, a forged Host).
Plain sockets only, so every test environment can use it."""

from __future__ import annotations

import os
import socket
import struct


def upgrade_request(host: str, path: str = '/', origin: str | None = None) -> bytes:
    """A websocket upgrade request written by hand (for what a client library will not send)."""
    extra = f'Origin: {origin}\r\n' if origin else ''
    return (f'GET {path} HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n'
            f'Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n{extra}\r\n').encode()


def raw_websocket(host: str, port: int, path: str = '/', rcvbuf: int | None = None) -> tuple[socket.socket, bytes]:
    """An upgraded connection on a plain socket, and the bytes that came after the response head."""
    sock = socket.create_connection((host, port), timeout=10)
    if rcvbuf:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    sock.sendall(upgrade_request(f'{host}:{port}', path))
    head = b''
    while b'\r\n\r\n' not in head:
        chunk = sock.recv(4096)
        assert chunk, f'the server closed during the handshake: {head!r}'
        head += chunk
    head, rest = head.split(b'\r\n\r\n', 1)
    assert head.startswith(b'HTTP/1.1 101'), head
    return sock, rest


def client_frame(opcode: int, payload: bytes) -> bytes:
    """A final, masked frame as a client sends it (RFC 6455 5.2)."""
    size = len(payload)
    if size < 126:
        header = bytes((0x80 | opcode, 0x80 | size))
    elif size <= 0xFFFF:
        header = struct.pack('!BBH', 0x80 | opcode, 0x80 | 126, size)
    else:
        header = struct.pack('!BBQ', 0x80 | opcode, 0x80 | 127, size)
    mask = os.urandom(4)
    return header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


def server_frame(take) -> tuple[int, bytes]:
    """(opcode, payload) of the next frame a server sends (unmasked, RFC 6455 5.2; final frames
    only: the gateway does not fragment), its bytes read with ``take(n)``."""
    first, second = take(2)
    size = second & 0x7F
    if size == 126:
        size = struct.unpack('!H', take(2))[0]
    elif size == 127:
        size = struct.unpack('!Q', take(8))[0]
    return first & 0x0F, take(size)


class ServerFrames:
    """The frames a server sends on a raw websocket (unmasked, RFC 6455 5.2), read by hand: a
    client that answers a ping only when the test says so (a stalled link reads nothing)."""

    def __init__(self, sock: socket.socket, rest: bytes = b''):
        self.sock, self.buffer = sock, rest

    def _take(self, n: int) -> bytes:
        while len(self.buffer) < n:
            chunk = self.sock.recv(65536)
            assert chunk, 'the server closed the connection'
            self.buffer += chunk
        data, self.buffer = self.buffer[:n], self.buffer[n:]
        return data

    def next(self) -> tuple[int, bytes]:
        """(opcode, payload) of the next frame."""
        return server_frame(self._take)

    def until(self, opcode: int, where=lambda payload: True) -> bytes:
        """The payload of the next frame of ``opcode`` that ``where`` accepts (others passed over)."""
        while True:
            op, payload = self.next()
            if op == opcode and where(payload):
                return payload
