"""Black-box tests over raw websocket frames: encodings, fragments, client-served actions."""

from __future__ import annotations

import base64
import json
import math
import struct
import time

import cbor2
import pytest
from rosbags.typesys import Stores, get_typestore

from tests.support.rawclient import Raw

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


@pytest.fixture
def raw(gateway):
    with Raw(gateway.ws_url) as client:
        yield client


def publish_op(m):
    return m.get('op') == 'publish'


def test_multiple_subscribers_with_cbor_raw(gateway, raw):
    subs = [Raw(gateway.ws_url) for _ in range(3)]
    try:
        for i, sub in enumerate(subs):
            sub.send({'op': 'subscribe', 'id': f'raw{i}', 'topic': '/raw/twist',
                      'type': 'geometry_msgs/msg/Twist', 'compression': 'cbor-raw'})
            sub.sync()
        raw.send({'op': 'advertise', 'topic': '/raw/twist', 'type': 'geometry_msgs/msg/Twist'})
        raw.send({'op': 'publish', 'topic': '/raw/twist',
                  'msg': {'linear': {'x': 1.5}, 'angular': {'z': -0.25}}})
        for sub in subs:
            msg = sub.expect(publish_op)
            body = msg['msg']
            assert set(body) == {'secs', 'nsecs', 'bytes'}
            assert len(body['bytes']) == 52 and body['bytes'][:4] == b'\x00\x01\x00\x00'
            twist = TYPESTORE.deserialize_cdr(body['bytes'], 'geometry_msgs/msg/Twist')
            assert (twist.linear.x, twist.angular.z) == (1.5, -0.25)
    finally:
        for sub in subs:
            sub.close()


def test_cbor_typed_arrays_and_json_nan(gateway, raw):
    with Raw(gateway.ws_url) as as_json:
        raw.send({'op': 'subscribe', 'topic': '/raw/scan', 'type': 'sensor_msgs/msg/LaserScan',
                  'compression': 'cbor'})
        as_json.send({'op': 'subscribe', 'topic': '/raw/scan', 'type': 'sensor_msgs/msg/LaserScan'})
        raw.sync()
        as_json.sync()
        with Raw(gateway.ws_url) as pub:
            pub.send({'op': 'publish', 'topic': '/raw/scan', 'type': 'sensor_msgs/msg/LaserScan',
                      'msg': {'ranges': [1.0, None, 2.5], 'range_max': 10.0}})
            cbor_msg = raw.expect(publish_op)['msg']
            json_msg = as_json.expect(publish_op)['msg']
    tag = cbor_msg['ranges']   # float32[] travels as an RFC 8746 typed array: tag 85, little-endian
    assert isinstance(tag, cbor2.CBORTag) and tag.tag == 85
    ranges = struct.unpack('<3f', tag.value)
    assert ranges[0] == 1.0 and math.isnan(ranges[1]) and ranges[2] == 2.5
    assert json_msg['ranges'] == [1.0, None, 2.5]   # NaN goes out as null, inside arrays too
    assert json_msg['header'] == {'stamp': {'sec': 0, 'nanosec': 0}, 'frame_id': ''}


def test_uint8_array_base64_round_trip(raw):
    data = bytes(range(256))
    raw.send({'op': 'subscribe', 'topic': '/raw/bytes', 'type': 'std_msgs/msg/UInt8MultiArray'})
    raw.send({'op': 'publish', 'topic': '/raw/bytes', 'type': 'std_msgs/msg/UInt8MultiArray',
              'msg': {'data': base64.b64encode(data).decode()}})
    msg = raw.expect(publish_op)['msg']
    assert base64.b64decode(msg['data']) == data
    raw.send({'op': 'publish', 'topic': '/raw/bytes', 'msg': {'data': [1, 2, 3]}})
    assert base64.b64decode(raw.expect(publish_op)['msg']['data']) == b'\x01\x02\x03'


def test_outgoing_fragments_and_png(raw):
    raw.send({'op': 'subscribe', 'topic': '/raw/big', 'type': 'std_msgs/msg/String', 'fragment_size': 100})
    raw.send({'op': 'publish', 'topic': '/raw/big', 'msg': {'data': 'x' * 1000}})
    pieces = []
    while not pieces or len(pieces) < pieces[0]['total']:
        pieces.append(raw.expect(lambda m: m.get('op') == 'fragment'))
    assert [p['num'] for p in pieces] == list(range(len(pieces)))
    whole = json.loads(''.join(p['data'] for p in pieces))
    assert whole['msg']['data'] == 'x' * 1000

    raw.send({'op': 'unsubscribe', 'topic': '/raw/big'})
    raw.send({'op': 'subscribe', 'topic': '/raw/big', 'type': 'std_msgs/msg/String', 'compression': 'png'})
    raw.send({'op': 'publish', 'topic': '/raw/big', 'msg': {'data': 'png!'}})
    png = raw.expect(lambda m: m.get('op') == 'png')
    from protocol.codec import decode_png
    assert decode_png(png['data'])['msg'] == {'data': 'png!'}


def test_incoming_fragments_are_reassembled(raw):
    call = json.dumps({'op': 'call_service', 'id': 'frag-call', 'service': '/add_two_ints',
                       'args': {'a': 20, 'b': 22}})
    parts = [call[i:i + 20] for i in range(0, len(call), 20)]
    for num, part in enumerate(parts):
        raw.send({'op': 'fragment', 'id': 'frag-call', 'data': part, 'num': num, 'total': len(parts)})
    reply = raw.expect(lambda m: m.get('id') == 'frag-call')
    assert reply['values'] == {'sum': 42} and reply['result'] is True


def test_cbor_request_frames(raw):
    raw.ws.send(cbor2.dumps({'op': 'call_service', 'id': 'cbor-call', 'service': '/add_two_ints',
                             'args': {'a': 1, 'b': 2}}))
    assert raw.expect(lambda m: m.get('id') == 'cbor-call')['values'] == {'sum': 3}


def test_best_effort_and_transient_local_qos(gateway, raw):
    raw.send({'op': 'advertise', 'topic': '/raw/qos', 'type': 'std_msgs/msg/String',
              'qos': {'reliability': 'best_effort', 'durability': 'transient_local', 'depth': 1}})
    raw.send({'op': 'publish', 'topic': '/raw/qos', 'msg': {'data': 'kept'}})
    with Raw(gateway.ws_url) as late:
        late.send({'op': 'subscribe', 'topic': '/raw/qos', 'type': 'std_msgs/msg/String'})
        assert late.expect(publish_op)['msg'] == {'data': 'kept'}


def test_client_served_action_with_feedback(gateway, raw):
    raw.send({'op': 'advertise_action', 'action': '/raw/count', 'type': 'example_interfaces/action/Fibonacci'})
    with Raw(gateway.ws_url) as caller:
        caller.wait_listed('/rosapi/action_servers', 'action_servers', '/raw/count')
        caller.send({'op': 'send_action_goal', 'id': 'g1', 'action': '/raw/count',
                     'action_type': 'example_interfaces/action/Fibonacci', 'args': {'order': 3}, 'feedback': True})
        goal = raw.expect(lambda m: m.get('op') == 'send_action_goal')
        assert goal['args'] == {'order': 3}
        raw.send({'op': 'action_feedback', 'action': '/raw/count', 'id': goal['id'], 'values': {'sequence': [0, 1]}})
        feedback = caller.expect(lambda m: m.get('op') == 'action_feedback')
        assert feedback['values'] == {'sequence': [0, 1]} and feedback['id'] == 'g1'
        raw.send({'op': 'action_result', 'action': '/raw/count', 'id': goal['id'], 'status': 4,
                  'result': True, 'values': {'sequence': [0, 1, 1, 2]}})
        result = caller.expect(lambda m: m.get('op') == 'action_result')
        assert result == {'op': 'action_result', 'action': '/raw/count', 'id': 'g1',
                          'values': {'sequence': [0, 1, 1, 2]}, 'status': 4, 'result': True}

        # a cancel reaches the serving client, which answers canceled
        caller.send({'op': 'send_action_goal', 'id': 'g2', 'action': '/raw/count',
                     'action_type': 'example_interfaces/action/Fibonacci', 'args': {'order': 9}})
        goal = raw.expect(lambda m: m.get('op') == 'send_action_goal')
        caller.send({'op': 'cancel_action_goal', 'id': 'g2', 'action': '/raw/count'})
        cancel = raw.expect(lambda m: m.get('op') == 'cancel_action_goal')
        assert cancel['id'] == goal['id']
        raw.send({'op': 'action_result', 'action': '/raw/count', 'id': goal['id'], 'status': 5,
                  'result': True, 'values': {'sequence': [0]}})
        assert caller.expect(lambda m: m.get('id') == 'g2')['status'] == 5

        # the serving client disconnects mid-goal: the caller gets an aborted result, not a hang
        caller.send({'op': 'send_action_goal', 'id': 'g3', 'action': '/raw/count',
                     'action_type': 'example_interfaces/action/Fibonacci', 'args': {'order': 2}})
        raw.expect(lambda m: m.get('op') == 'send_action_goal')
        raw.close()
        assert caller.expect(lambda m: m.get('id') == 'g3')['status'] == 6


def test_client_served_service_without_values_does_not_hang(gateway, raw):
    raw.send({'op': 'advertise_service', 'service': '/raw/trigger', 'type': 'std_srvs/srv/Trigger'})
    with Raw(gateway.ws_url) as caller:
        caller.wait_listed('/rosapi/services', 'services', '/raw/trigger')
        caller.send({'op': 'call_service', 'id': 'c1', 'service': '/raw/trigger'})
        request = raw.expect(lambda m: m.get('op') == 'call_service')
        assert request['id'].startswith('service_request:/raw/trigger:')
        raw.send({'op': 'service_response', 'service': '/raw/trigger', 'id': request['id'], 'result': True})
        reply = caller.expect(lambda m: m.get('id') == 'c1')
        assert reply['result'] is True and reply['values'] == {'success': False, 'message': ''}


def test_a_serving_client_gets_requests_named_as_it_advertised_them(gateway, raw):
    """The service and action names and the action type come back as the serving client wrote
    them (relative, short type): roslibjs and roslibpy route requests by the name."""
    raw.send({'op': 'advertise_service', 'service': 'raw/echo_trigger', 'type': 'std_srvs/Trigger'})
    raw.send({'op': 'advertise_action', 'action': 'raw/echo_fib', 'type': 'example_interfaces/Fibonacci'})
    raw.sync()
    with Raw(gateway.ws_url) as caller:
        caller.send({'op': 'call_service', 'id': 'c', 'service': '/raw/echo_trigger'})
        request = raw.expect(lambda m: m.get('op') == 'call_service')
        assert request['service'] == 'raw/echo_trigger' and 'type' not in request
        raw.send({'op': 'service_response', 'service': 'raw/echo_trigger', 'id': request['id'],
                  'values': {'success': True, 'message': 'echoed'}, 'result': True})
        assert caller.expect(lambda m: m.get('id') == 'c')['values'] == {'success': True, 'message': 'echoed'}
        caller.send({'op': 'send_action_goal', 'id': 'g', 'action': '/raw/echo_fib',
                     'action_type': 'example_interfaces/action/Fibonacci', 'args': {'order': 2}})
        goal = raw.expect(lambda m: m.get('op') == 'send_action_goal')
        assert (goal['action'], goal['action_type']) == ('raw/echo_fib', 'example_interfaces/Fibonacci')
        raw.send({'op': 'action_result', 'action': 'raw/echo_fib', 'id': goal['id'], 'status': 4,
                  'result': True, 'values': {'sequence': [0, 1, 1]}})
        result = caller.expect(lambda m: m.get('id') == 'g' and m.get('op') == 'action_result')
        assert (result['result'], result['values']) == (True, {'sequence': [0, 1, 1]})


def test_replies_to_ops_sent_without_an_id_have_no_id(raw):
    raw.send({'op': 'call_service', 'service': '/rosapi/get_time'})
    reply = raw.expect(lambda m: m.get('op') == 'service_response')
    assert reply['result'] is True and 'id' not in reply, reply
    raw.send({'op': 'call_service', 'service': '/add_two_ints', 'args': {'a': 'one', 'b': 2}})
    reply = raw.expect(lambda m: m.get('op') == 'service_response')
    assert reply['result'] is False and 'id' not in reply, reply
    raw.send({'op': 'subscribe', 'topic': '/raw/no_type_yet'})
    status = raw.status()
    assert 'cannot infer the type' in status['msg'] and 'id' not in status, status


def test_a_call_waits_for_a_service_that_appears_meanwhile(gateway, raw):
    """As rosbridge: a service that is not there yet is waited for up to a second."""
    with Raw(gateway.ws_url) as server:
        for n, typed in enumerate((True, False)):       # roslibjs sends no type
            service = f'/raw/late_{n}'
            call = {'op': 'call_service', 'id': f'late{n}', 'service': service}
            raw.send({**call, 'type': 'std_srvs/srv/Trigger'} if typed else call)
            raw.sync()          # the gateway has the call: the service does not exist yet
            server.send({'op': 'advertise_service', 'service': service, 'type': 'std_srvs/srv/Trigger'})
            request = server.expect(lambda m: m.get('op') == 'call_service')
            server.send({'op': 'service_response', 'service': service, 'id': request['id'],
                         'values': {'success': True, 'message': str(n)}, 'result': True})
            reply = raw.expect(lambda m: m.get('id') == f'late{n}')
            assert (reply['result'], reply['values']) == (True, {'success': True, 'message': str(n)})
    for typed in (True, False):
        started = time.monotonic()
        call = {'op': 'call_service', 'id': f'never{typed}', 'service': '/raw/never'}
        raw.send({**call, 'type': 'std_srvs/srv/Trigger'} if typed else call)
        reply = raw.expect(lambda m: m.get('id') == f'never{typed}')
        assert reply['result'] is False and '/raw/never' in reply['values'], reply
        assert 0.95 <= time.monotonic() - started < 4   # the 1 s wait for a server, not the 5 s call timeout
