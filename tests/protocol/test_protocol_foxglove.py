"""The Foxglove WebSocket protocol's frames, sans I/O: every client op parsed (and refused with its
op and field named), every server message written, parameter values both ways. The byte layouts
are checked against foxglove/foxglove-sdk's own encodings (its insta snapshots in
rust/foxglove/src/protocol/v1), not against this module's reading of the spec."""

from __future__ import annotations

import json
import math
import struct

import pytest

from protocol import foxglove as fg
from protocol.errors import ProtocolError

PAYLOAD = b'{"key": "value"}'


def test_the_subprotocol_is_chosen_from_what_the_client_offers():
    assert fg.choose(['foxglove.websocket.v1']) == 'foxglove.websocket.v1'
    assert fg.choose(['foxglove.sdk.v1', 'foxglove.websocket.v1']) == 'foxglove.sdk.v1'
    assert fg.choose(['mqtt', 'foxglove.websocket.v1']) == 'foxglove.websocket.v1'
    assert fg.choose([]) is None and fg.choose(None) is None   # roslibjs, roslibpy: rosbridge
    assert fg.choose(['rosbridge', 'foxglove.websocket.v2']) is None


# --- client ops ------------------------------------------------------------------------------

VALID = {
    'subscribe': ({'subscriptions': [{'id': 0, 'channelId': 3}, {'id': 1, 'channelId': 5}]},
                  fg.Subscribe((fg.Subscription(0, 3), fg.Subscription(1, 5)))),
    'unsubscribe': ({'subscriptionIds': [0, 1]}, fg.Unsubscribe((0, 1))),
    'advertise': ({'channels': [{'id': 1, 'topic': '/cmd', 'encoding': 'cdr', 'schemaName': 'geometry_msgs/msg/Twist'}]},
                  fg.Advertise((fg.ClientChannel(1, '/cmd', 'cdr', 'geometry_msgs/msg/Twist'),))),
    'unadvertise': ({'channelIds': [1, 2]}, fg.Unadvertise((1, 2))),
    'getParameters': ({'parameterNames': ['/n.a'], 'id': 'r1'}, fg.GetParameters(('/n.a',), 'r1')),
    'setParameters': ({'parameters': [{'name': '/n.a', 'value': 3}, {'name': '/n.b'}]},
                      fg.SetParameters((fg.Parameter('/n.a', 3), fg.Parameter('/n.b')))),
    'subscribeParameterUpdates': ({'parameterNames': []}, fg.SubscribeParameterUpdates(())),
    'unsubscribeParameterUpdates': ({'parameterNames': ['/n.a']}, fg.UnsubscribeParameterUpdates(('/n.a',))),
    'subscribeConnectionGraph': ({}, fg.SubscribeConnectionGraph()),
    'unsubscribeConnectionGraph': ({}, fg.UnsubscribeConnectionGraph()),
    'fetchAsset': ({'uri': 'package://r/a.stl', 'requestId': 9}, fg.FetchAsset('package://r/a.stl', 9)),
}


@pytest.mark.parametrize('op', sorted(VALID))
def test_each_json_op_parses(op):
    fields, expected = VALID[op]
    assert fg.parse_text(json.dumps({'op': op, **fields})) == expected
    assert set(VALID) == set(fg.JSON_OPS)


def test_the_client_channel_keeps_its_schema_when_it_sends_one():
    op = fg.parse_text(json.dumps({'op': 'advertise', 'channels': [
        {'id': 2, 'topic': 't', 'encoding': 'json', 'schemaName': 'std_msgs/String', 'schema': 'string data',
         'schemaEncoding': 'ros2msg'}]}))
    assert op.channels[0] == fg.ClientChannel(2, 't', 'json', 'std_msgs/String', 'string data', 'ros2msg')


@pytest.mark.parametrize('frame, op, field_and_why', [
    ({'op': 'subscribe', 'subscriptions': [{'id': 'seven', 'channelId': 1}]}, 'subscribe',
     "field 'subscriptions[0].id' must be an integer, got string"),
    ({'op': 'subscribe', 'subscriptions': [{'id': 1}]}, 'subscribe', "field 'subscriptions[0].channelId' is required"),
    ({'op': 'subscribe', 'subscriptions': {'id': 1}}, 'subscribe', "field 'subscriptions' must be an array, got object"),
    ({'op': 'subscribe', 'subscriptions': [{'id': -1, 'channelId': 1}]}, 'subscribe',
     "field 'subscriptions[0].id' must be an integer from 0 to 4294967295, got -1"),
    ({'op': 'subscribe', 'subscriptions': [{'id': 2**32, 'channelId': 1}]}, 'subscribe',
     "field 'subscriptions[0].id' must be an integer from 0 to 4294967295"),
    ({'op': 'unsubscribe', 'subscriptionIds': [1, None]}, 'unsubscribe', "field 'subscriptionIds[1]' must be an integer"),
    ({'op': 'advertise', 'channels': [{'id': 1, 'topic': '/t', 'encoding': 'cdr'}]}, 'advertise',
     "field 'channels[0].schemaName' is required"),
    ({'op': 'advertise', 'channels': [{'id': 1, 'topic': 5, 'encoding': 'cdr', 'schemaName': 'a/B'}]}, 'advertise',
     "field 'channels[0].topic' must be a string, got number"),
    ({'op': 'getParameters', 'parameterNames': 'x'}, 'getParameters', "field 'parameterNames' must be an array"),
    ({'op': 'setParameters', 'parameters': [{'name': '/n.a', 'value': 1, 'type': 'int8'}]}, 'setParameters',
     "field 'parameters[0].type' must be one of byte_array, float64, float64_array, got 'int8'"),
    ({'op': 'setParameters', 'parameters': [{'name': '/n.a', 'value': 'not base64!', 'type': 'byte_array'}]},
     'setParameters', "field 'parameters[0].value' a byte_array value is base64 text"),
    ({'op': 'setParameters', 'parameters': [{'name': '/n.a', 'value': [1, 'x'], 'type': 'float64_array'}]},
     'setParameters', "field 'parameters[0].value' a float64_array value is an array of numbers"),
    ({'op': 'fetchAsset', 'uri': 'package://x'}, 'fetchAsset', "field 'requestId' is required"),
    ({'op': 'getParameters', 'parameterNames': None}, 'getParameters', "field 'parameterNames' must not be null"),
])
def test_a_bad_field_is_named_with_its_op(frame, op, field_and_why):
    with pytest.raises(ProtocolError) as caught:
        fg.parse_text(json.dumps(frame))
    assert caught.value.op == op
    assert caught.value.message.startswith(field_and_why), caught.value.message


def test_the_request_id_comes_back_with_an_error_that_has_one():
    with pytest.raises(ProtocolError) as caught:
        fg.parse_text(json.dumps({'op': 'getParameters', 'id': 'req-9'}))
    assert (caught.value.op, caught.value.id) == ('getParameters', 'req-9')


@pytest.mark.parametrize('frame, message', [
    ('{"op": "publish", "topic": "/t"}', "unknown op 'publish' (this server takes subscribe, unsubscribe, "),
    ('{"subscriptions": []}', "missing required field 'op'"),
    ('{"op": 3}', "field 'op' must be a string, got number"),
    ('[1, 2]', 'expected a JSON object, got array'),
    ('{"op": "subscribe", ', 'invalid JSON'),
])
def test_frames_that_are_no_op_at_all(frame, message):
    with pytest.raises(ProtocolError) as caught:
        fg.parse_text(frame)
    assert message.lower() in caught.value.message.lower(), caught.value.message


def test_client_message_data_as_the_sdk_writes_it():
    frame = bytes([0x01, 0x1e, 0x00, 0x00, 0x00]) + PAYLOAD   # foxglove-sdk: client message_data_encode
    assert fg.parse_binary(frame) == fg.MessageData(30, PAYLOAD)
    assert fg.parse_binary(memoryview(frame)) == fg.MessageData(30, PAYLOAD)
    assert fg.parse_binary(bytes([0x01, 2, 0, 0, 0])) == fg.MessageData(2, b'')


def test_a_service_call_request_as_the_sdk_writes_it():
    frame = bytes([0x02, 0x0a, 0, 0, 0, 0x0c, 0, 0, 0, 0x04, 0, 0, 0]) + b'json' + PAYLOAD   # service_call_request_encode
    assert fg.parse_binary(frame) == fg.ServiceCallRequest(10, 12, 'json', PAYLOAD)


@pytest.mark.parametrize('frame, op, message', [
    (b'', None, 'empty binary message'),
    (b'\x01\x02\x00', 'messageData', 'binary message of 3 bytes is too short for a channel id'),
    (b'\x02' + struct.pack('<II', 1, 2), 'serviceCallRequest', 'too short for service id, call id and encoding length'),
    (b'\x02' + struct.pack('<III', 1, 2, 99) + b'cdr', 'serviceCallRequest', 'encoding of 99 bytes runs past the end'),
    (b'\x02' + struct.pack('<III', 1, 2, 2) + b'\xff\xfe', 'serviceCallRequest', 'the encoding is not UTF-8 text'),
    (b'\x03' + b'\x00' * 20, 'playbackControlRequest', 'no playbackControl capability'),
    (b'\x7f', None, 'unknown binary opcode 0x7f'),
])
def test_bad_binary_frames(frame, op, message):
    with pytest.raises(ProtocolError) as caught:
        fg.parse_binary(frame)
    assert caught.value.op == op
    assert message in caught.value.message


# --- server messages -----------------------------------------------------------------------------

def test_message_data_header_as_the_sdk_writes_it():
    expected = bytes([0x01, 0x1e, 0, 0, 0, 0xd2, 0x04, 0, 0, 0, 0, 0, 0]) + PAYLOAD   # server message_data_encode
    assert fg.message_data_header(30, 1234) + PAYLOAD == expected
    assert len(fg.message_data_header(2**32 - 1, 2**64 - 1)) == 13


def test_service_call_response_as_the_sdk_writes_it():
    expected = bytes([0x03, 0x0a, 0, 0, 0, 0x0c, 0, 0, 0, 0x04, 0, 0, 0]) + b'json' + PAYLOAD   # service_call_response_encode
    assert fg.service_call_response(10, 12, 'json', PAYLOAD) == expected


def test_fetch_asset_responses():
    ok = fg.fetch_asset_response(7, b'STL')
    assert ok == struct.pack('<BIBI', 0x04, 7, 0, 0) + b'STL'
    refused = fg.fetch_asset_response(7, error='no assets')
    assert refused == struct.pack('<BIBI', 0x04, 7, 1, 9) + b'no assets'


def test_status_levels_as_numbers():
    assert json.loads(fg.status('warning', 'Oh no')) == {'op': 'status', 'level': 1, 'message': 'Oh no'}   # sdk snapshot
    assert json.loads(fg.status('warn', 'w'))['level'] == 1
    assert json.loads(fg.status('info', 'i'))['level'] == 0
    assert json.loads(fg.status('error', 'e', 'auth')) == {'op': 'status', 'level': 2, 'message': 'e', 'id': 'auth'}


def test_server_info_channels_and_services():
    info = json.loads(fg.server_info('rosgate (sim)', fg.CAPABILITIES, '42', {'ROS_DISTRO': 'jazzy'}))
    assert info == {'op': 'serverInfo', 'name': 'rosgate (sim)', 'capabilities': list(fg.CAPABILITIES),
                    'supportedEncodings': ['cdr', 'json'], 'sessionId': '42', 'metadata': {'ROS_DISTRO': 'jazzy'}}
    channel = fg.channel(3, '/chatter', 'std_msgs/msg/String', 'string data')
    assert json.loads(fg.advertise([channel])) == {'op': 'advertise', 'channels': [
        {'id': 3, 'topic': '/chatter', 'encoding': 'cdr', 'schemaName': 'std_msgs/msg/String',
         'schema': 'string data', 'schemaEncoding': 'ros2msg'}]}
    assert json.loads(fg.unadvertise([3])) == {'op': 'unadvertise', 'channelIds': [3]}
    service = fg.service(5, '/add', 'example_interfaces/srv/AddTwoInts',
                         ('example_interfaces/srv/AddTwoInts_Request', 'int64 a\nint64 b'),
                         ('example_interfaces/srv/AddTwoInts_Response', 'int64 sum'))
    assert service['request'] == {'encoding': 'cdr', 'schemaName': 'example_interfaces/srv/AddTwoInts_Request',
                                  'schemaEncoding': 'ros2msg', 'schema': 'int64 a\nint64 b'}
    assert (service['requestSchema'], service['responseSchema']) == ('int64 a\nint64 b', 'int64 sum')   # older clients
    assert json.loads(fg.advertise_services([service]))['services'][0]['response']['schema'] == 'int64 sum'
    assert json.loads(fg.unadvertise_services([5])) == {'op': 'unadvertiseServices', 'serviceIds': [5]}
    assert json.loads(fg.service_call_failure(5, 1, 'gone')) == {
        'op': 'serviceCallFailure', 'serviceId': 5, 'callId': 1, 'message': 'gone'}


def test_a_connection_graph_update_lists_names_and_sorted_ids():
    update = json.loads(fg.connection_graph_update({'/a': {'/n2', '/n1'}}, {'/a': frozenset()}, {'/s': {'/n1'}},
                                                   ['/gone'], ['/s0']))
    assert update == {'op': 'connectionGraphUpdate',
                      'publishedTopics': [{'name': '/a', 'publisherIds': ['/n1', '/n2']}],
                      'subscribedTopics': [{'name': '/a', 'subscriberIds': []}],
                      'advertisedServices': [{'name': '/s', 'providerIds': ['/n1']}],
                      'removedTopics': ['/gone'], 'removedServices': ['/s0']}


# --- parameters ----------------------------------------------------------------------------------

def test_parameter_names_split_at_the_first_dot():
    assert fg.split_parameter('/turtlesim.background_r') == ('/turtlesim', 'background_r')
    assert fg.split_parameter('/ns/node.qos_overrides./tf.depth') == ('/ns/node', 'qos_overrides./tf.depth')
    assert fg.split_parameter('node.p') == ('/node', 'p')
    for bad in ('/turtlesim', '.p', '/n.'):
        with pytest.raises(ValueError, match='"/node.parameter"'):
            fg.split_parameter(bad)
    assert fg.parameter_name('/n', 'p') == '/n.p'


def test_parameter_values_to_foxglove():
    assert fg.foxglove_parameter('/n.i', 3) == {'name': '/n.i', 'value': 3}
    assert fg.foxglove_parameter('/n.f', 3.0) == {'name': '/n.f', 'value': 3.0, 'type': 'float64'}   # 3.0 stays a double
    assert fg.foxglove_parameter('/n.b', True) == {'name': '/n.b', 'value': True}
    assert fg.foxglove_parameter('/n.s', 'x') == {'name': '/n.s', 'value': 'x'}
    assert fg.foxglove_parameter('/n.y', b'ABCD') == {'name': '/n.y', 'value': 'QUJDRA==', 'type': 'byte_array'}
    assert fg.foxglove_parameter('/n.fa', [1.0, 2.5]) == {'name': '/n.fa', 'value': [1.0, 2.5], 'type': 'float64_array'}
    assert fg.foxglove_parameter('/n.ia', (1, 2)) == {'name': '/n.ia', 'value': [1, 2]}
    assert fg.foxglove_parameter('/n.nan', math.nan) == {'name': '/n.nan', 'value': None, 'type': 'float64'}


def test_parameter_values_from_foxglove():
    assert fg.Parameter('/n.y', 'QUJDRA==', 'byte_array').ros_value() == b'ABCD'
    assert fg.Parameter('/n.f', 3, 'float64').ros_value() == 3.0
    assert type(fg.Parameter('/n.f', 3, 'float64').ros_value()) is float
    assert fg.Parameter('/n.fa', [1, 2.5], 'float64_array').ros_value() == [1.0, 2.5]
    assert fg.Parameter('/n.i', 3).ros_value() == 3
    assert fg.Parameter('/n.gone').value is fg.UNSET
    with pytest.raises(ValueError, match='a float64 value is a number'):
        fg.Parameter('/n.f', 'x', 'float64').ros_value()
