"""Hostile ops at a live gateway: each is refused with a status naming op and id, the connection
and everyone else's service carry on, and nothing the failed op began is left behind."""

from __future__ import annotations

import json
import struct
from urllib.request import urlopen

import cbor2
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from tests.support.process import proc_bytes
from tests.support.rawclient import Raw
from tests.support.rawsocket import client_frame, raw_websocket
from tests.support.wait import wait_for


@pytest.fixture
def raw(gateway):
    with Raw(gateway.ws_url) as client:
        yield client


def refusal(client: Raw, frame, id: str | None) -> dict:
    """Send frame, then a round trip; the error status for it (which came first)."""
    client.send(frame)
    status = client.status(id)
    assert status['level'] == 'error', status
    client.sync()
    return status


def test_lone_surrogates_get_a_status_and_the_connection_stays(raw):
    status = refusal(raw, '{"op": "subscribe", "topic": "/x\\ud800", "id": "s1"}', 's1')
    assert "field 'topic' is not valid Unicode" in status['msg']
    raw.send('{"op": "nope", "id": "a\\udc00"}')
    status = raw.status()
    assert 'id' not in status and "field 'id'" in status['msg']
    raw.sync()


def test_a_bad_name_cannot_break_rosapi_for_others(gateway):
    with Raw(gateway.ws_url) as evil, Raw(gateway.ws_url) as other:
        refusal(evil, '{"op": "advertise", "topic": "/evil\\ud800", "type": "std_msgs/msg/String", "id": "e"}', 'e')
        for service in ('/rosapi/topics', '/rosapi/topics_and_raw_types'):
            reply = other.call(service)
            assert reply['op'] == 'service_response' and reply['result'] is True, reply


def test_a_latched_message_with_a_bad_string_is_refused_and_late_subscribers_still_served(gateway):
    with Raw(gateway.ws_url) as pub, Raw(gateway.ws_url) as late:
        pub.send({'op': 'advertise', 'topic': '/hostile/latched', 'type': 'std_msgs/msg/String', 'latch': True})
        pub.send({'op': 'publish', 'topic': '/hostile/latched', 'msg': {'data': 'good'}})
        status = refusal(pub, '{"op": "publish", "topic": "/hostile/latched", "id": "bad", '
                              '"msg": {"data": "\\ud800"}}', 'bad')
        assert "field 'msg.data'" in status['msg']
        late.send({'op': 'subscribe', 'topic': '/hostile/latched', 'type': 'std_msgs/msg/String'})
        msg = late.expect(lambda m: m.get('op') == 'publish')
        assert msg['msg'] == {'data': 'good'}


@pytest.mark.parametrize('op', [
    {'op': 'subscribe', 'topic': '/x', 'id': 'b1', 'queue_length': -(10**5000)},
    {'op': 'call_service', 'service': '/add_two_ints', 'id': 'b2', 'timeout': 10**5000},
])
def test_cbor_bignums_get_a_status(raw, op):
    status = refusal(raw, cbor2.dumps(op), op['id'])
    assert 'integer of' in status['msg'] or 'must be <=' in status['msg']


def test_a_failed_subscribe_leaves_no_subscription(gateway):
    topic = '/hostile/leak'
    with Raw(gateway.ws_url) as c:
        frame = ('{"op": "subscribe", "id": "ov", "topic": "%s", "type": "std_msgs/msg/String", '
                 '"throttle_rate": 1%s}' % (topic, '0' * 400))
        assert 'throttle_rate' in refusal(c, frame, 'ov')['msg']
        assert c.call('/rosapi/subscribers', {'topic': topic})['values']['subscribers'] == []
    with Raw(gateway.ws_url) as c:
        assert c.call('/rosapi/subscribers', {'topic': topic})['values']['subscribers'] == []


def test_png_errors_carry_the_id(raw):
    refusal(raw, '{"op": "png", "id": "T7", "data": "!!!!"}', 'T7')


def test_rosapi_names_cannot_be_advertised(raw):
    status = refusal(raw, {'op': 'advertise_service', 'service': '/rosapi/topics', 'id': 'dup',
                           'type': 'rosapi_msgs/srv/Topics'}, 'dup')
    assert 'served by the gateway itself' in status['msg']
    services = raw.call('/rosapi/services')['values']['services']
    assert services.count('/rosapi/topics') == 1


def test_a_client_that_does_not_read_its_replies_is_closed_1008(start_gateway):
    gw = start_gateway('--send-buffer-limit', '65536')
    with Raw(gw.ws_url, max_queue=1) as lazy, Raw(gw.ws_url) as other:
        code = reason = None
        # ~20 MB of replies: more than loopback buffers hold, so the outbox bound is reached while
        # the client reads nothing. Then stop sending (a socket closed with unread data resets,
        # losing the close frame) and read: the close frame comes after what the socket holds.
        try:
            for i in range(10_000):
                lazy.send({'op': 'call_service', 'service': '/rosapi/topics_and_raw_types', 'id': f'c{i}'})
            wait_for(lambda: 'does not read its replies' in gw.log_text(), timeout=30)
            while True:
                lazy.recv(timeout=30)
        except TimeoutError:
            pytest.fail('the server never closed the connection of a client that does not read')
        except ConnectionClosed as e:
            code, reason = (e.rcvd.code, e.rcvd.reason) if e.rcvd else (1006, "")
        assert code == 1008 and 'not reading replies' in reason
        assert other.call('/rosapi/get_time')['values']['time']['sec'] > 0
    assert gw.alive


NON_READER_CALLS = 10_000      # 4.1 KB replies, ~41 MB: past the default bound (16 MiB) and the socket buffers
NON_READER_BATCH = 5           # calls per round trip of another client
NON_READER_GROWTH = 50_000_000   # issue 11: "< 50 MB"


def test_a_client_that_does_not_read_its_replies_costs_the_server_little_memory(start_gateway):
    """A client that stops reading and calls /rosapi/topics_and_raw_types 10,000 times (default
    limits): the gateway's peak RSS grows by less than 50 MB, and the memory is given back.

    The calls go in small batches, each followed by another client's round trip: sent all at once,
    most would be refused past --max-pending-calls with a short reply, and the replies would be
    made back to back on a fresh heap, where unused parts of a buffer never become resident
    (orjson's oversized buffers cost 70 MiB paced like this, 37 MiB in batches of 50)."""
    gw = start_gateway()
    with Raw(gw.ws_url) as other:
        for _ in range(20):   # imports and caches a first call makes are not the client's cost
            other.call('/rosapi/topics_and_raw_types')
        try:   # the peak RSS (VmHWM) starts again from the current RSS
            with open(f'/proc/{gw.pid}/clear_refs', 'w') as f:
                f.write('5')
        except OSError as e:
            pytest.skip(f'cannot reset the peak RSS of the gateway: {e}')
        before = proc_bytes(gw.pid, 'VmRSS')
        with Raw(gw.ws_url, max_queue=1) as lazy:
            try:
                for i in range(0, NON_READER_CALLS, NON_READER_BATCH):
                    lazy.send_together(*({'op': 'call_service', 'service': '/rosapi/topics_and_raw_types',
                                          'id': f'c{j}'} for j in range(i, i + NON_READER_BATCH)))
                    other.call('/rosapi/get_time')
                while True:
                    lazy.recv(timeout=30)
            except TimeoutError:
                pytest.fail('the server never closed the connection of a client that does not read')
            except ConnectionClosed:
                pass
        growth = proc_bytes(gw.pid, 'VmHWM') - before
        assert 'does not read its replies' in gw.log_text()
        assert growth < NON_READER_GROWTH, f'peak RSS grew by {growth / 2**20:.1f} MiB'
        wait_for(lambda: json.loads(urlopen(gw.http_url + 'health').read())['clients'] == 1, timeout=15)
        left = proc_bytes(gw.pid, 'VmRSS') - before
        assert left < 10 * 2**20, f'RSS is still {left / 2**20:.1f} MiB above where it was'
        assert other.call('/rosapi/get_time')['values']['time']['sec'] > 0


def closed_with(ws) -> tuple[list, int, str]:
    """Everything the server sent until it closed, and its close code and reason (1006: dropped)."""
    got = []
    try:
        while True:
            got.append(json.loads(ws.recv(timeout=10)))
    except TimeoutError:
        pytest.fail(f'the server did not close the connection; it sent {got[-5:]}')
    except ConnectionClosed as e:
        return got, *((e.rcvd.code, e.rcvd.reason) if e.rcvd else (1006, ''))


@pytest.mark.parametrize('compression', [None, 'deflate'])
def test_invalid_utf8_in_a_text_frame_gets_a_status_and_a_1007_close(gateway, start_gateway, compression):
    gw = start_gateway('--use-compression') if compression else gateway
    call = {'op': 'call_service', 'service': '/rosapi/get_time'}
    with Raw(gw.ws_url) as other, connect(gw.ws_url, compression=compression, open_timeout=10) as bad:
        bad.send(json.dumps({**call, 'id': 'before'}))
        bad.send(b'{"op": "subscribe", "topic": "/x\xff\xfe", "id": "u1"}', text=True)   # not UTF-8
        bad.send(json.dumps({**call, 'id': 'after'}))   # the connection has failed: never handled
        got, code, reason = closed_with(bad)
        assert (code, reason) == (1007, 'text frame is not valid UTF-8')
        assert [m.get('id') for m in got] == ['before', None], got
        status = got[1]
        assert status['op'] == 'status' and status['level'] == 'error', status
        assert 'not valid UTF-8 (byte 0xff at offset 32' in status['msg'], status
        assert other.call('/add_two_ints', {'a': 2, 'b': 3})['values'] == {'sum': 5}
    with Raw(gw.ws_url) as again:   # valid non-ASCII text is still text
        again.send('{"op": "nope", "id": "ä€"}')
        assert again.status('ä€')['level'] == 'error'
    assert gw.alive


def test_a_close_frame_whose_reason_is_not_utf8_is_answered(gateway):
    """websockets will not send such a frame: the handshake and frames are written by hand."""
    s, answer = raw_websocket(gateway.host, gateway.port, gateway.path)
    with s:
        s.sendall(client_frame(0x8, struct.pack('!H', 1000) + b'bye \xff'))
        while len(answer) < 4:
            chunk = s.recv(4096)
            assert chunk, f'the server dropped the connection without a close frame (got {answer!r})'
            answer += chunk
        # the connection fails with 1007 (RFC 6455 8.1: the reason is not UTF-8); on tornado's
        # protocol (--no-fast-io, TLS, deflate) the close is echoed with its code alone: test_fast_io.py
        assert answer[0] == 0x88 and struct.unpack('!H', answer[2:4])[0] == 1007, answer
    with Raw(gateway.ws_url) as other:
        other.sync()
