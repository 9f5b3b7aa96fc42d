"""Parsing and validation of every incoming op."""

from __future__ import annotations

import dataclasses

import pytest

from protocol import ops
from protocol.errors import ProtocolError
from protocol.ops import OPS, parse_op

# op -> (minimal valid object, expected parsed dataclass)
MINIMAL = {
    'advertise': ({'topic': '/t', 'type': 'std_msgs/String'},
                  ops.Advertise('/t', 'std_msgs/String', None, False, 100, None)),
    'unadvertise': ({'topic': '/t'}, ops.Unadvertise('/t')),
    'publish': ({'topic': '/t', 'msg': {}}, ops.Publish('/t', {}, None, False, 100, None)),
    'subscribe': ({'topic': '/t'}, ops.Subscribe('/t', None, None, 0, 0, None, 'none', None)),
    'unsubscribe': ({'topic': '/t'}, ops.Unsubscribe('/t')),
    'call_service': ({'service': '/s'}, ops.CallService('/s', None, None, None, None, None, 'none')),
    'service_response': ({'service': '/s'}, ops.ServiceResponse('/s', None, None, True)),
    'advertise_service': ({'service': '/s', 'type': 'std_srvs/Trigger'},
                          ops.AdvertiseService('/s', 'std_srvs/Trigger')),
    'unadvertise_service': ({'service': '/s'}, ops.UnadvertiseService('/s')),
    'advertise_action': ({'action': '/a', 'type': 'x/Y'}, ops.AdvertiseAction('/a', 'x/Y')),
    'unadvertise_action': ({'action': '/a'}, ops.UnadvertiseAction('/a')),
    'send_action_goal': ({'action': '/a', 'action_type': 'x/Y'},
                         ops.SendActionGoal('/a', 'x/Y', None, None, False, None, 'none')),
    'cancel_action_goal': ({'action': '/a', 'id': 'g1'}, ops.CancelActionGoal('/a', 'g1')),
    'action_feedback': ({'action': '/a'}, ops.ActionFeedback('/a')),
    'action_result': ({'action': '/a'}, ops.ActionResult('/a', None, None, None, True)),
    'set_level': ({'level': 'info'}, ops.SetLevel('info')),
    'auth': ({}, ops.Auth()),
    'fragment': ({'id': 'f', 'data': '{', 'num': 0, 'total': 2}, ops.Fragment('f', '{', 0, 2)),
    'png': ({'data': 'iVBO'}, ops.Png('iVBO')),
    'ping': ({}, ops.Ping()),
}

REQUIRED = {
    'advertise': ['topic', 'type'], 'unadvertise': ['topic'], 'publish': ['topic', 'msg'],
    'subscribe': ['topic'], 'unsubscribe': ['topic'], 'call_service': ['service'],
    'service_response': ['service'], 'advertise_service': ['service', 'type'],
    'unadvertise_service': ['service'], 'advertise_action': ['action', 'type'],
    'unadvertise_action': ['action'], 'send_action_goal': ['action', 'action_type'],
    'cancel_action_goal': ['action', 'id'], 'action_feedback': ['action'], 'action_result': ['action'],
    'set_level': ['level'], 'auth': [], 'fragment': ['id', 'data', 'num', 'total'], 'png': ['data'],
    'ping': [],
}


def error_of(obj) -> ProtocolError:
    with pytest.raises(ProtocolError) as info:
        parse_op(obj)
    return info.value


def test_every_op_has_a_case_and_a_wire_name():
    assert set(MINIMAL) == set(OPS) == set(REQUIRED)
    for name, cls in OPS.items():
        assert cls.OP == name
        assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen
        assert hasattr(cls, '__slots__')


@pytest.mark.parametrize('name', sorted(MINIMAL))
def test_minimal_op_parses_with_reference_defaults(name):
    obj, expected = MINIMAL[name]
    parsed = parse_op({'op': name, **obj})
    assert parsed == expected
    assert type(parsed) is OPS[name]


@pytest.mark.parametrize('name', sorted(MINIMAL))
def test_parsed_ops_are_immutable(name):
    parsed = parse_op({'op': name, **MINIMAL[name][0]})
    field = dataclasses.fields(parsed)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(parsed, field, 'x')


@pytest.mark.parametrize(('name', 'field'), [(n, f) for n, fs in sorted(REQUIRED.items()) for f in fs])
def test_missing_required_field_names_op_id_and_field(name, field):
    obj = {'op': name, **MINIMAL[name][0], 'id': 'req-7'}
    del obj[field]
    err = error_of(obj)
    assert err.op == name
    assert err.id == (None if field == 'id' else 'req-7')
    assert err.message == f"{name}: missing required field '{field}'"
    assert err.level == 'error'


@pytest.mark.parametrize(('name', 'field'), [(n, f) for n, fs in sorted(REQUIRED.items()) for f in fs if f != 'id'])
def test_required_field_given_as_null_is_an_error(name, field):
    err = error_of({'op': name, **MINIMAL[name][0], field: None})
    assert err.op == name and f"'{field}'" in err.message and 'null' in err.message


def test_full_subscribe_as_roslibpy_sends_it():
    parsed = parse_op({'op': 'subscribe', 'id': 'subscribe:/chatter:1', 'type': 'std_msgs/String',
                       'topic': '/chatter', 'compression': 'cbor', 'throttle_rate': 100, 'queue_length': 5,
                       'fragment_size': 1000, 'qos': {'durability': 'transient_local'}})
    assert parsed == ops.Subscribe('/chatter', 'subscribe:/chatter:1', 'std_msgs/String', 100, 5, 1000, 'cbor',
                                   {'durability': 'transient_local'})


def test_full_ops_keep_every_field():
    assert parse_op({'op': 'advertise', 'topic': '/t', 'type': 'a/B', 'id': 'x', 'latch': True, 'queue_size': 1,
                     'qos': {}}) == ops.Advertise('/t', 'a/B', 'x', True, 1, {})
    assert parse_op({'op': 'publish', 'topic': '/t', 'msg': {'data': 1}, 'latch': True, 'queue_size': 3,
                     'type': 'a/B'}) == ops.Publish('/t', {'data': 1}, None, True, 3, 'a/B')
    assert parse_op({'op': 'call_service', 'service': '/s', 'id': 'c', 'args': [1, 2], 'type': 'a/B',
                     'timeout': 2.5, 'fragment_size': 10, 'compression': 'png'}) == ops.CallService(
        '/s', 'c', [1, 2], 'a/B', 2.5, 10, 'png')
    assert parse_op({'op': 'service_response', 'service': '/s', 'id': 'service_request:/s:1',
                     'values': 'it broke', 'result': False}) == ops.ServiceResponse(
        '/s', 'service_request:/s:1', 'it broke', False)
    assert parse_op({'op': 'send_action_goal', 'action': '/a', 'action_type': 'x/Y', 'id': 'g',
                     'args': {'order': 5}, 'feedback': True, 'fragment_size': 9, 'compression': 'cbor'}) == \
        ops.SendActionGoal('/a', 'x/Y', 'g', {'order': 5}, True, 9, 'cbor')
    assert parse_op({'op': 'action_result', 'action': '/a', 'id': 'g', 'status': 4, 'values': {'s': [1]},
                     'result': True}) == ops.ActionResult('/a', 'g', 4, {'s': [1]}, True)
    assert parse_op({'op': 'action_feedback', 'action': '/a', 'id': 'g', 'values': {'p': []}}) == \
        ops.ActionFeedback('/a', 'g', {'p': []})
    assert parse_op({'op': 'auth', 'mac': 'm', 'client': 'c', 'dest': 'd', 'rand': 'r', 't': 1, 'level': 'admin',
                     'end': 2}) == ops.Auth(None, 'm', 'c', 'd', 'r', 1, 'admin', 2)


def test_integer_ids_become_strings_and_extras_are_ignored():
    parsed = parse_op({'op': 'unsubscribe', 'topic': '/t', 'id': 42, 'extra': [1], 'compression': 'bogus'})
    assert parsed == ops.Unsubscribe('/t', '42')
    assert parse_op({'op': 'fragment', 'id': 7, 'data': '', 'num': 0, 'total': 1}).id == '7'


def test_null_optional_fields_take_defaults():
    parsed = parse_op({'op': 'subscribe', 'topic': '/t', 'type': None, 'throttle_rate': None, 'id': None,
                       'fragment_size': None, 'compression': None})
    assert parsed == ops.Subscribe('/t')


@pytest.mark.parametrize(('obj', 'message'), [
    ({'op': 'subscribe', 'topic': '/t', 'throttle_rate': '100'},
     "subscribe: field 'throttle_rate' must be an integer, got string"),
    ({'op': 'subscribe', 'topic': '/t', 'queue_length': True},
     "subscribe: field 'queue_length' must be an integer, got boolean"),
    ({'op': 'subscribe', 'topic': '/t', 'throttle_rate': 1.5},
     "subscribe: field 'throttle_rate' must be an integer, got number"),
    ({'op': 'subscribe', 'topic': '/t', 'throttle_rate': -1},
     "subscribe: field 'throttle_rate' must be >= 0, got -1"),
    ({'op': 'subscribe', 'topic': '/t', 'fragment_size': 0},
     "subscribe: field 'fragment_size' must be >= 1, got 0"),
    ({'op': 'subscribe', 'topic': '/t', 'compression': 'gzip'},
     "subscribe: field 'compression' must be one of none, png, cbor, cbor-raw, got 'gzip'"),
    ({'op': 'subscribe', 'topic': 5},
     "subscribe: field 'topic' must be a string, got number"),
    ({'op': 'subscribe', 'topic': '/t', 'qos': []},
     "subscribe: field 'qos' must be an object, got array"),
    ({'op': 'advertise', 'topic': '/t', 'type': 'a/B', 'latch': 'true'},
     "advertise: field 'latch' must be a boolean, got string"),
    ({'op': 'publish', 'topic': '/t', 'msg': 'hello'},
     "publish: field 'msg' must be an object, got string"),
    ({'op': 'publish', 'topic': '/t', 'msg': [1, 2]},
     "publish: field 'msg' must be an object, got array"),
    ({'op': 'call_service', 'service': '/s', 'timeout': '5'},
     "call_service: field 'timeout' must be a number, got string"),
    ({'op': 'call_service', 'service': '/s', 'timeout': True},
     "call_service: field 'timeout' must be a number, got boolean"),
    ({'op': 'call_service', 'service': '/s', 'timeout': -1},
     "call_service: field 'timeout' must be >= 0, got -1"),
    ({'op': 'call_service', 'service': '/s', 'args': 'a=1'},
     "call_service: field 'args' must be an object or an array, got string"),
    ({'op': 'service_response', 'service': '/s', 'result': 1},
     "service_response: field 'result' must be a boolean, got number"),
    ({'op': 'send_action_goal', 'action': '/a', 'action_type': 'x/Y', 'feedback': 'yes'},
     "send_action_goal: field 'feedback' must be a boolean, got string"),
    ({'op': 'action_result', 'action': '/a', 'status': 'succeeded'},
     "action_result: field 'status' must be an integer, got string"),
    ({'op': 'set_level', 'level': 'debug'},
     "set_level: field 'level' must be one of info, warning, error, none, got 'debug'"),
    ({'op': 'fragment', 'id': 'f', 'data': 'x', 'num': -1, 'total': 2},
     "fragment: field 'num' must be >= 0, got -1"),
    ({'op': 'fragment', 'id': 'f', 'data': 'x', 'num': 0, 'total': 0},
     "fragment: field 'total' must be >= 1, got 0"),
    ({'op': 'fragment', 'id': 'f', 'data': 5, 'num': 0, 'total': 1},
     "fragment: field 'data' must be a string, got number"),
    ({'op': 'unadvertise', 'topic': '/t', 'id': True},
     "unadvertise: field 'id' must be a string, got boolean"),
    ({'op': 'unadvertise', 'topic': '/t', 'id': 1.5},
     "unadvertise: field 'id' must be a string, got number"),
])
def test_wrong_field_types_are_named(obj, message):
    err = error_of(obj)
    assert err.message == message
    assert err.op == obj['op']


def test_error_carries_the_id_of_the_failing_op():
    err = error_of({'op': 'subscribe', 'id': 'subscribe:/x:3', 'topic': '/x', 'throttle_rate': 'fast'})
    assert (err.op, err.id) == ('subscribe', 'subscribe:/x:3')
    assert error_of({'op': 'subscribe', 'id': 9, 'topic': 1}).id == '9'


def test_numbers_accepted_where_floats_are_expected():
    assert parse_op({'op': 'call_service', 'service': '/s', 'timeout': 3}).timeout == 3
    assert parse_op({'op': 'call_service', 'service': '/s', 'timeout': 0.25}).timeout == 0.25


def test_set_level_accepts_warn_as_warning():
    assert parse_op({'op': 'set_level', 'level': 'warn'}).level == 'warning'
    for level in ('info', 'warning', 'error', 'none'):
        assert parse_op({'op': 'set_level', 'level': level, 'id': 'l'}) == ops.SetLevel(level, 'l')


@pytest.mark.parametrize(('obj', 'message', 'op', 'mid'), [
    ({'op': 'foo', 'id': 'x'}, "unknown op 'foo'", 'foo', 'x'),
    ({'id': 'x', 'topic': '/t'}, "missing required field 'op'", None, 'x'),
    ({'op': 3}, "field 'op' must be a string, got number", None, None),
    ([1, 2], 'expected a JSON object, got array', None, None),
    ('publish', 'expected a JSON object, got string', None, None),
    (None, 'expected a JSON object, got null', None, None),
])
def test_envelope_errors(obj, message, op, mid):
    err = error_of(obj)
    assert (err.message, err.op, err.id) == (message, op, mid)
