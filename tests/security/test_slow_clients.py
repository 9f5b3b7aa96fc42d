"""Clients that hold a connection and send nothing: a stalled upload (with or without a token,
with or without --auth), a connection that never finishes its headers, and a websocket that
never authenticates under --auth are all closed, by --body-timeout, --idle-connection-timeout
and --auth-timeout (short here, 30 to 60 s by default)."""

from __future__ import annotations

import select
import socket
import time

from tests.support.wsclient import Client

DEADLINE = 30.0   # s; the timeouts below are 1 s


def open_socket(gw) -> socket.socket:
    return socket.create_connection((gw.host, gw.port), timeout=10)


def stalled_upload(gw, size: int, sent: int) -> socket.socket:
    """A POST announcing ``size`` bytes of body that sends ``sent`` of them, then nothing."""
    s = open_socket(gw)
    s.sendall((f'PUT /api/programs/stalled HTTP/1.1\r\nHost: {gw.host}:{gw.port}\r\n'
               f'Content-Type: application/json\r\nContent-Length: {size}\r\n\r\n').encode() + b'{' + b' ' * (sent - 1))
    return s


def all_closed(sockets: list[socket.socket], timeout: float) -> float:
    """Read each socket until the server closes it; the seconds that took (fails at timeout)."""
    start = time.monotonic()
    open_ = list(sockets)
    while open_:
        left = start + timeout - time.monotonic()
        assert left > 0, f'{len(open_)} of {len(sockets)} connections still open after {timeout} s'
        ready, _, _ = select.select(open_, [], [], min(left, 1.0))
        for s in ready:
            try:
                data = s.recv(65536)
            except ConnectionResetError:
                data = b''
            if not data:
                open_.remove(s)
                s.close()
    return time.monotonic() - start


def test_stalled_uploads_and_idle_connections_are_closed(launch, tokens_file):
    gw = launch('--auth', tokens_file, '--body-timeout', '1', '--idle-connection-timeout', '1')
    # no token: 65,000 bytes is under the size read without one (the login form's), so it is read
    uploads = [stalled_upload(gw, 65_000, 1024) for _ in range(100)]
    silent = [open_socket(gw) for _ in range(10)]                          # connected, no request at all
    half = [open_socket(gw) for _ in range(10)]
    for s in half:
        s.sendall(f'GET / HTTP/1.1\r\nHost: {gw.host}:{gw.port}\r\n'.encode())   # headers never finished
    took = all_closed(uploads + silent + half, DEADLINE)
    print(f'120 stalled connections closed within {took:.2f} s')
    assert gw.alive


def test_a_stalled_large_upload_in_open_mode_is_closed(launch):
    gw = launch('--body-timeout', '1')
    uploads = [stalled_upload(gw, 4 * 2**20, 64 * 1024) for _ in range(5)]
    took = all_closed(uploads, DEADLINE)
    print(f'5 stalled 4 MiB uploads closed within {took:.2f} s')
    assert gw.alive


def test_an_unauthenticated_websocket_is_closed_with_a_status(launch, tokens_file):
    gw = launch('--auth', tokens_file, '--auth-timeout', '1')
    idle = [Client(gw.ws_url) for _ in range(20)]
    with Client(gw.ws_url, 'operator-token-3d4e5f') as signed_in:   # authenticated at connect: kept
        for c in idle:
            assert c.closed_code(DEADLINE) == 1008
            said = [m for m in c.seen if m.get('op') == 'status' and m.get('level') == 'error']
            assert said and 'not authenticated within 1 s' in said[-1]['msg'], c.seen
            c.close()
        assert signed_in.call('/rosapi/get_time')['result'] is True
