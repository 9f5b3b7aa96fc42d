"""Bad input gets a clear status naming op and id; nothing else is disturbed; the server lives."""

from __future__ import annotations

import json
import threading
import time

import pytest
import roslibpy
import websockets

from tests.support.rawclient import Raw
from tests.support.wait import wait_for


@pytest.fixture
def raw(gateway):
    with Raw(gateway.ws_url) as client:
        yield client


@pytest.fixture
def bystander(gateway):
    """A client subscribed to a steady stream: it must keep receiving whatever others do."""
    stop = threading.Event()
    got: list[int] = []
    with Raw(gateway.ws_url) as pub, Raw(gateway.ws_url) as sub:
        sub.send({'op': 'subscribe', 'topic': '/bystander', 'type': 'std_msgs/msg/Int32'})
        sub.sync()
        pub.send({'op': 'advertise', 'topic': '/bystander', 'type': 'std_msgs/msg/Int32'})

        def pump():
            i = 0
            while not stop.is_set():
                pub.send({'op': 'publish', 'topic': '/bystander', 'msg': {'data': i}})
                i += 1
                try:
                    while True:
                        got.append(sub.recv(timeout=0.01)['msg']['data'])
                except TimeoutError:
                    pass

        thread = threading.Thread(target=pump, daemon=True)
        thread.start()
        yield got
        before = len(got)
        wait_for(lambda: len(got) > before + 5)   # still flowing after the abuse
        stop.set()
        thread.join(5)
    assert got == list(range(len(got)))   # nothing lost, nothing reordered


CASES = [
    ('{"op": "subscribe", "topic": ', None, 'JSON'),
    ('[1, 2, 3]', None, 'object'),
    (json.dumps({'op': 'teleport_me', 'id': 'x1'}), 'x1', 'teleport_me'),
    (json.dumps({'op': 'subscribe', 'id': 's1'}), 's1', 'topic'),
    (json.dumps({'op': 'subscribe', 'id': 's2', 'topic': '/a', 'throttle_rate': 'fast'}), 's2', 'throttle_rate'),
    (json.dumps({'op': 'subscribe', 'id': 's3', 'topic': '/a', 'type': 'nope/msg/Nope'}), 's3', 'nope/msg/Nope'),
    (json.dumps({'op': 'subscribe', 'id': 's4', 'topic': '/does/not/exist'}), 's4', '/does/not/exist'),
    (json.dumps({'op': 'subscribe', 'id': 's5', 'topic': '/a', 'type': 'std_msgs/String',
                 'compression': 'zip'}), 's5', 'compression'),
    (json.dumps({'op': 'advertise', 'id': 'a1', 'topic': '/bystander', 'type': 'std_msgs/msg/String'}), 'a1', 'Int32'),
    (json.dumps({'op': 'publish', 'id': 'p1', 'topic': '/typed/twist', 'type': 'geometry_msgs/msg/Twist',
                 'msg': {'linear': {'q': 1}}}), 'p1', 'linear.q'),
    (json.dumps({'op': 'publish', 'id': 'p2', 'topic': '/typed/twist2', 'type': 'geometry_msgs/msg/Twist',
                 'msg': {'linear': {'x': 'fast'}}}), 'p2', 'linear.x'),
    (json.dumps({'op': 'publish', 'id': 'p3', 'topic': '/typed/int', 'type': 'std_msgs/msg/UInt8',
                 'msg': {'data': 300}}), 'p3', 'data'),
    (json.dumps({'op': 'unsubscribe', 'id': 'u1'}), 'u1', 'topic'),
    (json.dumps({'op': 'action_result', 'id': 'r1', 'action': '/x', 'status': 4, 'result': True}), 'r1', 'r1'),
]


@pytest.mark.parametrize('frame,id,needle', CASES, ids=[c[2] for c in CASES])
def test_bad_op_gets_status_naming_op_and_id(raw, bystander, frame, id, needle):
    raw.send(frame)
    status = raw.status()
    assert status['level'] in ('error', 'warning')
    assert status.get('id') == id
    assert needle in status['msg']
    op = json.loads(frame).get('op') if frame.startswith('{"op": "') and frame.endswith('}') else None
    if op:
        assert status['msg'].startswith(op)
    # the same connection still works
    raw.send({'op': 'call_service', 'id': 'after', 'service': '/add_two_ints', 'args': {'a': 1, 'b': 2}})
    assert raw.expect(lambda m: m.get('id') == 'after')['values'] == {'sum': 3}


def test_unknown_service_and_action_fail_with_result_false(raw):
    raw.send({'op': 'call_service', 'id': 'ns', 'service': '/no/such/service'})
    reply = raw.expect(lambda m: m.get('id') == 'ns')
    assert reply['op'] == 'service_response' and reply['result'] is False
    assert '/no/such/service' in reply['values']
    raw.send({'op': 'send_action_goal', 'id': 'na', 'action': '/no/such/action',
              'action_type': 'example_interfaces/action/Fibonacci', 'args': {'order': 1}})
    reply = raw.expect(lambda m: m.get('id') == 'na')
    assert reply['op'] == 'action_result' and reply['result'] is False and 'status' in reply
    assert '/no/such/action' in reply['values']


def test_a_goal_the_action_refuses_is_aborted_and_logged_as_the_clients_mistake(raw, gateway):
    log_before = len(gateway.log_text())
    raw.send({'op': 'send_action_goal', 'id': 'big', 'action': '/fibonacci',
              'action_type': 'example_interfaces/action/Fibonacci', 'args': {'order': 100}})
    reply = raw.expect(lambda m: m.get('op') == 'action_result' and m.get('id') == 'big')
    assert reply['status'] == 6 and reply['values'] == {'sequence': []}, reply   # ABORTED
    logged = gateway.log_text()[log_before:]   # the sim logs before it answers
    assert 'WARNING' in logged and 'order must be between 0 and 46' in logged, logged
    assert 'Traceback' not in logged and 'ERROR' not in logged, logged


def test_warnings_reach_clients_that_ask_for_them(raw):
    raw.send({'op': 'set_level', 'level': 'warning'})
    raw.send({'op': 'cancel_action_goal', 'id': 'c1', 'action': '/fibonacci'})
    status = raw.status('c1')
    assert status['level'] == 'warning' and status['msg'].startswith('cancel_action_goal (id c1)')
    raw.send({'op': 'unsubscribe', 'id': 'u2', 'topic': '/never/subscribed'})
    assert '/never/subscribed' in raw.status('u2')['msg']


def test_set_level_filters_status(raw):
    raw.send({'op': 'set_level', 'level': 'none'})
    raw.send({'op': 'subscribe', 'id': 'quiet'})
    raw.send({'op': 'call_service', 'id': 'after', 'service': '/add_two_ints', 'args': {'a': 1, 'b': 1}})
    raw.expect(lambda m: m.get('id') == 'after')
    assert not [m for m in raw.seen if m.get('op') == 'status']


def test_client_served_service_that_never_answers(start_gateway):
    gw = start_gateway('--default-call-service-timeout', '0.5', '--robot', 'none')
    with Raw(gw.ws_url) as server, Raw(gw.ws_url) as caller:
        server.send({'op': 'advertise_service', 'service': '/silent', 'type': 'std_srvs/srv/Trigger'})
        caller.wait_listed('/rosapi/services', 'services', '/silent')
        caller.send({'op': 'call_service', 'id': 'c', 'service': '/silent', 'timeout': 5})
        started = time.monotonic()
        reply = caller.expect(lambda m: m.get('id') == 'c', timeout=5)
        assert reply['result'] is False and 'did not answer' in reply['values']
        assert time.monotonic() - started < 3


def test_oversized_frames(start_gateway):
    gw = start_gateway('--max-message-size', '65536', '--robot', 'none')
    with Raw(gw.ws_url) as client, Raw(gw.ws_url) as other:
        big = json.dumps({'op': 'publish', 'id': 'big', 'topic': '/big', 'type': 'std_msgs/msg/String',
                          'msg': {'data': 'x' * 100_000}})
        client.send(big)
        status = client.status()
        assert status.get('id') == 'big' and 'exceeds' in status['msg']
        # far beyond the limit the connection is closed with 1009; others carry on
        client.send('x' * (65536 * 5))
        with pytest.raises(websockets.ConnectionClosed) as closed:
            client.expect(lambda m: False, timeout=5)
        assert closed.value.rcvd.code == 1009
        other.send({'op': 'call_service', 'id': 'ok', 'service': '/add_two_ints', 'args': {'a': 2, 'b': 2}})
        assert other.expect(lambda m: m.get('id') == 'ok')['values'] == {'sum': 4}


def test_fragment_flood_is_refused(gateway, raw, bystander):
    # 64 incomplete messages may wait; the 65th is past the bound: a status, then close 1008
    try:
        for i in range(200):
            raw.send({'op': 'fragment', 'id': f'flood{i}', 'data': 'y' * 1000, 'num': 0, 'total': 1000})
    except websockets.ConnectionClosed:
        pass   # closed while sending: what it said before is still read below
    with pytest.raises(websockets.ConnectionClosed) as closed:
        raw.expect(lambda m: False, timeout=10)
    assert closed.value.rcvd.code == 1008
    errors = [m for m in raw.seen if m.get('op') == 'status' and m.get('level') == 'error']
    assert [m['id'] for m in errors] == ['flood64'] and 'too many incomplete messages' in errors[0]['msg']
    with Raw(gateway.ws_url) as other:   # others are served meanwhile
        other.send({'op': 'call_service', 'id': 'after', 'service': '/add_two_ints', 'args': {'a': 5, 'b': 5}})
        assert other.expect(lambda m: m.get('id') == 'after', timeout=10)['values'] == {'sum': 10}


def test_roslibpy_survives_status_and_png_ops(ros, gateway):
    # a roslibpy client provoking errors keeps working afterwards
    bad = roslibpy.Topic(ros, '/typed/twist3', 'geometry_msgs/msg/Twist')
    bad.advertise()
    bad.publish(roslibpy.Message({'linear': {'nope': 1}}))
    ros.send_on_ready(roslibpy.Message({'op': 'subscribe', 'topic': '/nothing/here'}))
    service = roslibpy.Service(ros, '/add_two_ints', 'example_interfaces/srv/AddTwoInts')
    assert service.call(roslibpy.ServiceRequest({'a': 7, 'b': 8}), timeout=5)['sum'] == 15
    assert ros.is_connected


def test_slow_client_does_not_stall_others(start_gateway):
    gw = start_gateway('--send-buffer-limit', str(2 * 2**20), '--robot', 'none')
    payload = 'z' * 100_000
    slow = websockets.sync.client.connect(gw.ws_url, max_size=None, max_queue=1, compression=None,
                                          legacy=True)
    try:
        slow.send(json.dumps({'op': 'set_level', 'level': 'warning'}))
        slow.send(json.dumps({'op': 'subscribe', 'topic': '/flood', 'type': 'std_msgs/msg/String'}))
        with Raw(gw.ws_url) as fast, Raw(gw.ws_url) as pub:
            fast.send({'op': 'subscribe', 'topic': '/flood', 'type': 'std_msgs/msg/String'})
            fast.sync()
            pub.send({'op': 'advertise', 'topic': '/flood', 'type': 'std_msgs/msg/String'})
            count = 300   # 30 MB through a client that never reads
            received = 0
            started = time.monotonic()
            for i in range(count):   # lock-step: each message must reach the fast client promptly
                pub.send({'op': 'publish', 'topic': '/flood', 'msg': {'data': f'{i:06d}' + payload}})
                msg = fast.recv(timeout=5)
                assert int(msg['msg']['data'][:6]) == i
                received += 1
            elapsed = time.monotonic() - started
        assert received == count and elapsed < 30
        # the stalled client was told it is losing messages, once it reads again
        seen = []
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            msg = json.loads(slow.recv(timeout=5))
            seen.append(msg)
            if msg.get('op') == 'status':
                break
        assert any(m.get('op') == 'status' and 'not reading fast enough' in m['msg'] for m in seen)
        assert len([m for m in seen if m.get('op') == 'publish']) < count
    finally:
        slow.close()
    assert gw.alive


@pytest.mark.parametrize('kind, advertise, unadvertise', [
    ('topic', {'op': 'advertise', 'type': 'std_msgs/msg/Int32'}, 'unadvertise'),
    ('service', {'op': 'advertise_service', 'type': 'std_srvs/srv/Empty'}, 'unadvertise_service'),
    ('action', {'op': 'advertise_action', 'type': 'example_interfaces/action/Fibonacci'}, 'unadvertise_action'),
])
def test_unadvertising_what_this_client_does_not_advertise_is_a_warning(raw, kind, advertise, unadvertise):
    name = f'/mine/{kind}'
    raw.send({'op': 'set_level', 'level': 'warning'})
    raw.send({'op': unadvertise, 'id': 'u1', kind: name})
    status = raw.status('u1')
    assert status['level'] == 'warning' and f'{name} is not advertised by this client' in status['msg'], status
    raw.send({**advertise, kind: name})
    raw.send({'op': unadvertise, 'id': 'u2', kind: name})     # this one is the client's: no status
    raw.send({'op': unadvertise, 'id': 'u3', kind: name})     # and now it is gone again
    assert raw.status()['id'] == 'u3'
