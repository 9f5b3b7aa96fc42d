"""The rclpy backend's type handling: IDL type strings (no ROS needed) and, where rclpy imports,
message <-> dict over every field kind of test_msgs, plus ROS arguments."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from gateway.backends.rclpy.types import parse_idl_type
from protocol.msgdefs import Field, UnknownType

from tests.support.contract import rclpy_missing, same


@pytest.mark.parametrize('idl, field', [
    ('double', Field('f', 'float64')),
    ('float', Field('f', 'float32')),
    ('boolean', Field('f', 'bool')),
    ('octet', Field('f', 'byte')),
    ('uint8', Field('f', 'uint8')),
    ('string', Field('f', 'string')),
    ('string<=10', Field('f', 'string', string_bound=10)),
    ('wstring', Field('f', 'wstring')),
    ('sequence<uint8>', Field('f', 'uint8', array=0)),
    ('sequence<int32, 5>', Field('f', 'int32', array=0, bound=5)),
    ('double[9]', Field('f', 'float64', array=9)),
    ('string<10>', Field('f', 'string', string_bound=10)),
    ('wstring<3>', Field('f', 'wstring', string_bound=3)),
    ('sequence<string<4>, 3>', Field('f', 'string', array=0, bound=3, string_bound=4)),
    ('sequence<string<4>>', Field('f', 'string', array=0, string_bound=4)),
    ('string<4>[2]', Field('f', 'string', array=2, string_bound=4)),
    ('sequence<string<=4, 3>', Field('f', 'string', array=0, bound=3, string_bound=4)),
    ('geometry_msgs/Vector3', Field('f', 'geometry_msgs/msg/Vector3')),
    ('sequence<geometry_msgs/Point>', Field('f', 'geometry_msgs/msg/Point', array=0)),
    ('sequence<test_msgs/BasicTypes, 3>', Field('f', 'test_msgs/msg/BasicTypes', array=0, bound=3)),
    ('test_msgs/Constants[3]', Field('f', 'test_msgs/msg/Constants', array=3)),
])
def test_parse_idl_type(idl, field):
    assert parse_idl_type('f', idl) == field


def test_parse_idl_type_rejects_unknown():
    with pytest.raises(UnknownType, match='f'):
        parse_idl_type('f', 'fixed<5, 2>')


def test_import_without_rclpy():
    """The gateway imports the backend module on machines without ROS."""
    code = ('import sys; import gateway.backends.rclpy.backend as m; '
            'assert "rclpy" not in sys.modules; print(m.RclpyBackend.name)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'rclpy'


needs_rclpy = pytest.mark.skipif(rclpy_missing() is not None, reason=f'rclpy does not import here: {rclpy_missing()}')


def _test_msgs():
    try:
        import test_msgs.msg  # noqa: F401
    except ImportError:
        pytest.skip('test_msgs is not installed')


@needs_rclpy
def test_every_field_kind_round_trips():
    """test_msgs/Arrays and BoundedSequences hold every primitive as fixed and bounded arrays."""
    _test_msgs()
    from gateway.backends.rclpy.types import Converter, RosDefinitions
    from protocol.convert import from_json
    defs = RosDefinitions()
    convert = Converter(defs)
    for type, size in (('test_msgs/msg/Arrays', 3), ('test_msgs/msg/BoundedSequences', 2),
                       ('test_msgs/msg/UnboundedSequences', 2)):
        msgdef = defs.msg(type)
        values = {
            'bool_values': [True, False, True][:size], 'byte_values': bytes([0, 255, 7][:size]),
            'char_values': bytes([65, 66, 67][:size]), 'float32_values': [1.5, math.nan, -2.0][:size],
            'float64_values': [math.inf, 0.1, -1e300][:size], 'int8_values': [-128, 127, 0][:size],
            'uint8_values': bytes([1, 2, 3][:size]), 'int16_values': [-32768, 32767, 1][:size],
            'uint16_values': [65535, 0, 1][:size], 'int32_values': [-2**31, 2**31 - 1, 5][:size],
            'uint32_values': [2**32 - 1, 0, 9][:size], 'int64_values': [-2**63, 2**63 - 1, 3][:size],
            'uint64_values': [2**64 - 1, 0, 4][:size], 'string_values': ['a', 'ü', ''][:size],
            'basic_types_values': [{'byte_value': 200, 'char_value': 66, 'float32_value': 0.25}] * size,
        }
        msg = from_json(defs, msgdef, values)
        cls = defs.msg_class(type)
        back = convert.to_dict(convert.from_dict(cls, msg))
        for key, value in values.items():
            got = back[key]
            if key == 'basic_types_values':
                assert [(g['byte_value'], g['char_value'], g['float32_value']) for g in got] \
                    == [(200, 66, 0.25)] * size
            elif key == 'float32_values' and size > 1:
                assert got[0] == 1.5 and math.isnan(got[1])
            else:
                assert got == value, (type, key, got)
        assert isinstance(back['byte_values'], bytes) and isinstance(back['uint8_values'], bytes)
        # and through CDR (what the middleware carries) unchanged
        from rclpy.serialization import deserialize_message, serialize_message
        again = convert.to_dict(deserialize_message(serialize_message(convert.from_dict(cls, msg)), cls))
        assert same(again, back)


@needs_rclpy
def test_constants_and_bounds():
    _test_msgs()
    from gateway.backends.rclpy.types import RosDefinitions
    defs = RosDefinitions()
    consts = {name: value for name, _, value in defs.msg('test_msgs/msg/Constants').constants}
    assert consts['BOOL_CONST'] is True and isinstance(consts['INT64_CONST'], int)
    assert isinstance(consts['FLOAT64_CONST'], float) and consts['BYTE_CONST'] == 50
    strings = {f.name: f for f in defs.msg('test_msgs/msg/Strings').fields}
    assert strings['bounded_string_value'].string_bound == 22
    with pytest.raises(UnknownType, match='not_a_pkg'):
        defs.msg('not_a_pkg/msg/Nothing')
    with pytest.raises(UnknownType, match='NoSuchType'):
        defs.msg('std_msgs/msg/NoSuchType')


@needs_rclpy
async def test_ros_args_remap():
    import os
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    from gateway.backends.rclpy.backend import RclpyBackend
    backend = RclpyBackend('gw', ros_args=['--ros-args', '-r', '__ns:=/robot7'])
    await backend.start()
    try:
        assert backend.node_name == '/robot7/gw'
        assert backend.msg_def('std_msgs/String').fields[0].name == 'data'
    finally:
        await backend.stop()
