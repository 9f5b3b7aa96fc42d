"""The rclpy backend's own CDR path (gateway.backends.rclpy.cdr) against rclpy's: for every message
it compiles, the same bytes out and the same dict in; anything it does not take exactly as given
is left to the Converter."""

from __future__ import annotations

import math

import pytest

from tests.support.contract import rclpy_missing, same

pytestmark = pytest.mark.skipif(rclpy_missing() is not None,
                                reason=f'rclpy does not import here: {rclpy_missing()}')

# type -> (a CDR reader is compiled, a CDR writer is compiled); the rest goes through rclpy's
# message objects. Writers cover scalars, strings, nested messages and uint8[] only: NavSatFix and
# Imu have float64[9], BasicTypes, Nested and Defaults have byte and char, Empty is one placeholder
# byte; readers leave out bool and string arrays and arrays of messages.
COMPILED = {
    'std_msgs/msg/String': (True, True), 'std_msgs/msg/Header': (True, True),
    'std_msgs/msg/Int64': (True, True), 'std_msgs/msg/Bool': (True, True),
    'std_msgs/msg/Float32': (True, True), 'geometry_msgs/msg/Twist': (True, True),
    'geometry_msgs/msg/PoseStamped': (True, True), 'sensor_msgs/msg/Image': (True, True),
    'sensor_msgs/msg/NavSatFix': (True, False), 'sensor_msgs/msg/Imu': (True, False),
    'sensor_msgs/msg/CompressedImage': (True, True), 'test_msgs/msg/BasicTypes': (True, False),
    'test_msgs/msg/Arrays': (False, False), 'test_msgs/msg/BoundedSequences': (False, False),
    'test_msgs/msg/UnboundedSequences': (False, False), 'test_msgs/msg/Strings': (True, True),
    'test_msgs/msg/Nested': (True, False), 'test_msgs/msg/MultiNested': (False, False),
    'test_msgs/msg/WStrings': (False, False), 'test_msgs/msg/Defaults': (True, False),
    'test_msgs/msg/Empty': (True, False),
}
TYPES = list(COMPILED)


@pytest.fixture(scope='module')
def convert():
    from gateway.backends.rclpy.types import Converter, RosDefinitions
    defs = RosDefinitions()
    return defs, Converter(defs)


def _sample(defs, type: str) -> dict:
    """A message with every field set to something other than its default."""
    from protocol.convert import from_json
    msgdef = defs.msg(type)
    values = {}
    for f in msgdef.fields:
        n = f.array if f.array else (2 if f.bound != 1 else 1)
        if not f.primitive:
            one = _sample(defs, f.type)
            values[f.name] = one if f.array is None else [one] * n
            continue
        one = {'bool': True, 'string': 'hé', 'wstring': 'w', 'float32': 1.5, 'float64': -2.25e100,
               'int64': -2**63, 'uint64': 2**64 - 1, 'int8': -7, 'int32': 2**31 - 1}.get(f.type, 200)
        if f.type in ('int16', 'uint16'):
            one = 300
        if f.type == 'char':
            one = 66
        if f.array is None:
            values[f.name] = one
        elif f.is_bytes:
            values[f.name] = bytes([one]) * n
        else:
            values[f.name] = [one] * n
    return from_json(defs, msgdef, values)


def _import(type: str):
    pkg = type.split('/')[0]
    try:
        __import__(f'{pkg}.msg')
    except ImportError:
        pytest.skip(f'{pkg} is not installed')


@pytest.mark.parametrize('type', TYPES)
def test_same_bytes_and_dicts_as_rclpy(convert, type):
    from rclpy.serialization import deserialize_message, serialize_message
    _import(type)
    defs, conv = convert
    cls = defs.msg_class(type)
    msg = _sample(defs, type)
    data = serialize_message(conv.from_dict(cls, msg))
    expected = conv.to_dict(deserialize_message(data, cls))
    read, write = conv.cdr_reader(cls), conv.cdr_writer(cls)
    if read is not None:
        assert same(read(data), expected), type
    if write is not None:
        ours = write(msg)      # padding bytes may differ: rmw leaves them uninitialised
        assert len(ours) == len(data) and ours[:4] == data[:4], type
        assert same(conv.to_dict(deserialize_message(ours, cls)), expected), type
    assert (read is not None, write is not None) == COMPILED[type], type


def test_left_to_the_converter(convert):
    """Values rclpy would coerce, reject or default are not encoded here (gateway.backends.rclpy.cdr.Slow)."""
    from gateway.backends.rclpy.cdr import Slow
    _import('test_msgs/msg/BasicTypes')
    defs, conv = convert
    plain = {f.name: f for f in defs.msg('test_msgs/msg/BasicTypes').fields if f.type not in ('byte', 'char')}
    assert conv.cdr_writer(defs.msg_class('test_msgs/msg/BasicTypes')) is None    # byte is bytes in rclpy

    def plan(cls):
        return [(n, f, s) for n, f, s in conv._plan(cls) if n in plain]
    from gateway.backends.rclpy.cdr import writer
    write = writer(plan, defs.msg_class('test_msgs/msg/BasicTypes'))
    good = {k: v for k, v in _sample(defs, 'test_msgs/msg/BasicTypes').items() if k in plain}
    write(good)
    for key, value in [('int32_value', 2**31), ('int32_value', 1.0), ('int32_value', True),
                       ('uint8_value', -1), ('bool_value', 1), ('float32_value', 1e39),
                       ('float64_value', '1.5'), ('float64_value', None), ('float64_value', 10**400)]:
        with pytest.raises(Slow):
            write({**good, key: value})
    with pytest.raises(Slow):
        write({k: v for k, v in good.items() if k != 'int8_value'})
    for value in (math.inf, -math.inf, math.nan, 3.4e38):    # as rclpy takes them
        assert write({**good, 'float32_value': value})
    string = conv.cdr_writer(defs.msg_class('std_msgs/msg/String'))
    for value in ['a\x00b', '\ud800', b'x', 5]:
        with pytest.raises(Slow):
            string({'data': value})
    assert string({'data': 'x', 'extra': 1}) == string({'data': 'x'})
    _import('test_msgs/msg/Strings')
    strings = conv.cdr_writer(defs.msg_class('test_msgs/msg/Strings'))
    sample = _sample(defs, 'test_msgs/msg/Strings')
    with pytest.raises(Slow):
        strings({**sample, 'bounded_string_value': 'x' * 23})


def test_reader_leaves_odd_bytes_to_rclpy(convert):
    from gateway.backends.rclpy.cdr import Slow
    defs, conv = convert
    read = conv.cdr_reader(defs.msg_class('std_msgs/msg/String'))
    assert read(b'\x00\x01\x00\x00\x03\x00\x00\x00ab\x00') == {'data': 'ab'}
    for data in [b'\x00\x01\x00\x00\x04\x00\x00\x00a\x00b\x00', b'\x00\x01\x00\x00\x03\x00\x00\x00\xff\xfe\x00',
                 b'\x00\x00\x00\x00\x00\x00\x00\x03ab\x00', b'\x00\x01\x00\x00\x09\x00\x00\x00ab\x00']:
        with pytest.raises(Slow):
            read(data)
