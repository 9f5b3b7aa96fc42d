"""The websocket on picows after tornado's HTTP (gateway/web/fastio.py), and tornado alone where picows
cannot or may not carry a connection (deflate, TLS, --no-fast-io, no wheel): the same answers either
way, the frames of one socket read in one write to each client, messages in several frames joined,
protocol errors closed with their code, and the seam a second kind of session plugs into (the
subprotocol chosen by the handler)."""

from __future__ import annotations

import asyncio
import json
import socket
import struct

import pytest
import tornado.httpserver
import tornado.netutil
import tornado.web
import tornado.websocket
import websockets
from websockets.sync.client import connect

from gateway.web.fastio import Connection, available
from tests.support.rawclient import Raw
from tests.support.rawsocket import client_frame, raw_websocket, server_frame

STRING = 'std_msgs/msg/String'
TORNADO = 'TornadoServer'   # tornado's 101 names it; picows's says nothing of itself
# a gateway without the compiled wheels: their imports fail as where no wheel exists
NO_WHEELS = ("import sys\n"
             "class NoWheel:\n"
             "    def find_spec(self, name, path=None, target=None):\n"
             "        if name.split('.')[0] in ('picows', 'uvloop', 'aiofastnet'):\n"
             "            raise ImportError(f'no wheel for {name} here')\n"
             "sys.meta_path.insert(0, NoWheel())\n")

pytestmark = pytest.mark.skipif(not available(), reason='picows is not installed')


@pytest.fixture(scope='module')
def tornado_gw(start_gateway):
    return start_gateway('--no-fast-io', '--robot', 'none')


@pytest.fixture(scope='module')
def wheelless_gw(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('nowheels')
    (folder / 'sitecustomize.py').write_text(NO_WHEELS)
    return start_gateway('--robot', 'none', env={'PYTHONPATH': str(folder)})


def server_header(url: str) -> str:
    """The Server header of the 101 (tornado names itself), after a round trip on the connection."""
    with connect(url, open_timeout=10) as ws:
        ws.send(json.dumps({'op': 'call_service', 'service': '/rosapi/get_time', 'id': 't'}))
        reply = json.loads(ws.recv(timeout=10))
        assert reply['id'] == 't' and reply['result'] is True, reply
        return ws.response.headers.get('Server', '')


def test_plain_connections_go_to_picows_and_the_rest_stay_with_tornado(gateway, tornado_gw, wheelless_gw):
    assert TORNADO not in server_header(gateway.ws_url)
    assert TORNADO in server_header(gateway.ws_url + '?compression=deflate')   # deflate is tornado's
    assert TORNADO in server_header(tornado_gw.ws_url)
    assert TORNADO in server_header(wheelless_gw.ws_url)
    assert gateway.alive and tornado_gw.alive and wheelless_gw.alive


def segments_in(sock: socket.socket) -> int:
    """TCP segments this socket has received (Linux's tcp_info.tcpi_segs_in)."""
    info = sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 256)
    return struct.unpack_from('I', info, 140)[0]


def test_the_messages_of_one_read_reach_a_subscriber_in_one_write(gateway):
    """20 publishes in one TCP write: the subscriber's 20 messages come as one segment, not 20."""
    topic = '/fastio/burst'
    with Raw(gateway.ws_url) as sub, Raw(gateway.ws_url) as pub:
        sub.send({'op': 'subscribe', 'topic': topic, 'type': STRING, 'queue_length': 100})
        sub.sync()
        pub.send({'op': 'advertise', 'topic': topic, 'type': STRING})
        pub.sync()
        pub.send_together({'op': 'publish', 'topic': topic, 'msg': {'data': 'warm'}})
        assert sub.expect(lambda m: m.get('op') == 'publish')['msg']['data'] == 'warm'
        before = segments_in(sub.ws.socket)
        pub.send_together(*({'op': 'publish', 'topic': topic, 'msg': {'data': f'{i:02d}'}} for i in range(20)))
        got = [sub.expect(lambda m: m.get('op') == 'publish', timeout=30)['msg']['data'] for _ in range(20)]
        segments = segments_in(sub.ws.socket) - before
    assert got == [f'{i:02d}' for i in range(20)]
    assert segments <= 3, f'{segments} segments for one read of 20 publishes'


@pytest.mark.parametrize('which', ['picows', 'tornado'])
def test_a_message_in_several_frames_is_joined(gateway, tornado_gw, which):
    gw = gateway if which == 'picows' else tornado_gw
    with connect(gw.ws_url, open_timeout=10) as ws:
        op = json.dumps({'op': 'call_service', 'service': '/rosapi/get_time', 'id': 'parts'})
        ws.send([op[:10], op[10:11], op[11:]])   # a text message in three frames
        reply = json.loads(ws.recv(timeout=10))
        assert reply['id'] == 'parts' and reply['result'] is True, reply


def frames_until_close(sock: socket.socket, rest: bytes) -> list[tuple[int, bytes]]:
    """Every frame the server sends until its close frame (included)."""
    buffer = bytearray(rest)

    def take(n: int) -> bytes:
        while len(buffer) < n:
            chunk = sock.recv(65536)
            assert chunk, f'the server dropped the connection without a close frame (got {bytes(buffer)!r})'
            buffer.extend(chunk)
        out = bytes(buffer[:n])
        del buffer[:n]
        return out

    frames = [server_frame(take)]
    while frames[-1][0] != 0x8:
        frames.append(server_frame(take))
    return frames


def call(id: str) -> bytes:
    """An op answered at once (its status), before anything else is read."""
    return client_frame(0x1, json.dumps({'op': 'no_such_op', 'id': id}).encode())


@pytest.mark.parametrize('bad', [
    client_frame(0x0, b'"op"}'),                                          # a continuation of nothing
    bytes([0xC1]) + client_frame(0x1, b'{"op": "nope"}')[1:],             # RSV1 without deflate
    bytes([0x01]) + client_frame(0x1, b'{"op":')[1:] + client_frame(0x1, b'"nope"}'),   # a message inside one
], ids=['lone continuation', 'rsv1', 'interleaved'])
def test_a_protocol_error_closes_1002_after_what_came_before_it(gateway, bad):
    s, rest = raw_websocket(gateway.host, gateway.port, gateway.path)
    with s:
        s.sendall(call('before') + bad + call('after'))   # one write: one read on the server
        frames = frames_until_close(s, rest)
    replies = [json.loads(payload)['id'] for opcode, payload in frames[:-1]]
    assert replies == ['before'], frames
    assert struct.unpack('!H', frames[-1][1][:2])[0] == 1002, frames[-1]
    with Raw(gateway.ws_url) as other:
        other.sync()


def test_a_message_past_the_hard_limit_in_many_frames_is_closed_1009(start_gateway):
    gw = start_gateway('--max-message-size', '65536', '--robot', 'none')   # frames past 4 x that close
    with connect(gw.ws_url, open_timeout=10, max_size=None) as ws:
        ws.send(['x' * 60_000] * 5)   # 300 kB in five frames, each well below the limit
        with pytest.raises(websockets.ConnectionClosed) as closed:
            ws.recv(timeout=10)
    assert closed.value.rcvd is not None and closed.value.rcvd.code == 1009
    with Raw(gw.ws_url) as other:
        other.sync()


def test_tornado_echoes_a_close_whose_reason_is_not_utf8(tornado_gw):
    s, rest = raw_websocket(tornado_gw.host, tornado_gw.port, tornado_gw.path)
    with s:
        s.sendall(client_frame(0x8, struct.pack('!H', 1000) + b'bye \xff'))
        frames = frames_until_close(s, rest)
    assert frames == [(0x8, struct.pack('!H', 1000))]   # the close echoed, its code alone


def test_a_client_close_is_echoed_with_its_code_after_what_came_before_it(gateway):
    s, rest = raw_websocket(gateway.host, gateway.port, gateway.path)
    with s:
        s.sendall(call('before') + client_frame(0x8, struct.pack('!H', 4000) + b'bye'))
        frames = frames_until_close(s, rest)
    assert [json.loads(p)['id'] for _, p in frames[:-1]] == ['before']
    assert frames[-1] == (0x8, struct.pack('!H', 4000))


# --- the seam: a handler that picks its session by subprotocol, carried by picows -----------------

class Picker(tornado.websocket.WebSocketHandler):
    """What a second kind of session needs of the websocket: the subprotocol it was chosen by,
    send, close, and the messages in order."""

    def get_websocket_protocol(self):
        return Connection(self) if Connection.carries(self) else super().get_websocket_protocol()

    def select_subprotocol(self, subprotocols):
        return 'foxglove.websocket.v1' if 'foxglove.websocket.v1' in subprotocols else None

    def open(self):
        self.kind = self.selected_subprotocol or 'rosbridge'
        self.text_frame = False

    def on_message(self, message):
        if message == b'close':
            self.close(4001, 'asked')
            return
        self.ws_connection.send(f'{self.kind}:{message.decode()}'.encode(), False)


async def test_a_session_chosen_by_subprotocol_plugs_into_the_picows_connection():
    sockets = tornado.netutil.bind_sockets(0, '127.0.0.1')
    server = tornado.httpserver.HTTPServer(tornado.web.Application([('/', Picker)]))
    server.add_sockets(sockets)
    url = f'ws://127.0.0.1:{sockets[0].getsockname()[1]}/'
    try:
        async with websockets.connect(url, subprotocols=['foxglove.websocket.v1']) as ws:
            assert ws.subprotocol == 'foxglove.websocket.v1'
            assert TORNADO not in ws.response.headers.get('Server', '')
            await ws.send('hello')
            assert await asyncio.wait_for(ws.recv(), 10) == 'foxglove.websocket.v1:hello'
            await ws.send('close')
            with pytest.raises(websockets.ConnectionClosed) as closed:
                await asyncio.wait_for(ws.recv(), 10)
            assert (closed.value.rcvd.code, closed.value.rcvd.reason) == (4001, 'asked')
        async with websockets.connect(url) as ws:
            assert ws.subprotocol is None
            await ws.send('hi')
            assert await asyncio.wait_for(ws.recv(), 10) == 'rosbridge:hi'
    finally:
        server.stop()
        await server.close_all_connections()



def test_the_keepalive_closes_a_silent_peer_and_keeps_one_that_answers(start_gateway):
    """--websocket-ping-interval / --websocket-ping-timeout on the picows path: every connection is
    pinged, also one that keeps sending (a proxy times out on what the gateway sends); one that
    answers with pongs stays open, one that does not is closed."""
    gw = start_gateway('--robot', 'none', '--websocket-ping-interval', '0.5', '--websocket-ping-timeout', '0.5')
    silent, rest_silent = raw_websocket(gw.host, gw.port, gw.path)
    answering, rest = raw_websocket(gw.host, gw.port, gw.path)
    with silent, answering:
        buffer = bytearray(rest)

        def take(n: int) -> bytes:
            while len(buffer) < n:
                chunk = answering.recv(65536)
                assert chunk, 'the gateway closed a connection that answered its pings'
                buffer.extend(chunk)
            out = bytes(buffer[:n])
            del buffer[:n]
            return out

        pings = 0
        answering.sendall(call('busy'))
        while pings < 3:   # three pings answered: past the timeout of the first twice over
            opcode, payload = server_frame(take)
            if opcode == 0x9:
                answering.sendall(client_frame(0xA, payload))
                pings += 1
            else:   # the answer to an op: the client keeps the gateway busy with another
                assert json.loads(payload)['id'] == 'busy', payload
                answering.sendall(call('busy'))
        answering.sendall(call('alive'))
        while (frame := server_frame(take))[0] != 0x1 or json.loads(frame[1])['id'] != 'alive':
            if frame[0] == 0x9:
                answering.sendall(client_frame(0xA, frame[1]))
        silent.settimeout(30)
        got = bytearray(rest_silent)
        while True:   # a ping, then the close (or the end of the connection)
            chunk = silent.recv(65536)
            if not chunk:
                break
            got.extend(chunk)
        assert got[:1] == b'\x89', bytes(got[:20])   # it was pinged before it was dropped
