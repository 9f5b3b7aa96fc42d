"""Message JSON rules, CBOR typed arrays and CDR, all driven by the message definitions."""

from __future__ import annotations

import base64
import math
import struct

import cbor2
import orjson
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol.codec import dumps, encode_cbor
from protocol.convert import default_message, from_args, from_cdr, from_json, to_cbor, to_cdr
from protocol.errors import ConversionError, ProtocolError

ROUND = settings(max_examples=40, deadline=None, database=None)


def conv_error(defs, type_, value) -> ConversionError:
    with pytest.raises(ConversionError) as info:
        from_json(defs, defs.msg(type_), value)
    return info.value


def wire(obj):
    """What a JSON client sees."""
    return orjson.loads(dumps(obj))


# --- defaults -----------------------------------------------------------------------------------


def test_missing_fields_take_defaults_including_nested(defs):
    twist = defs.msg('geometry_msgs/msg/Twist')
    assert from_json(defs, twist, {}) == {'linear': {'x': 0.0, 'y': 0.0, 'z': 0.0},
                                          'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}
    assert from_json(defs, twist, {'angular': {'z': 2}}) == {'linear': {'x': 0.0, 'y': 0.0, 'z': 0.0},
                                                             'angular': {'x': 0.0, 'y': 0.0, 'z': 2.0}}
    assert type(from_json(defs, twist, {'angular': {'z': 2}})['angular']['z']) is float


def test_defaults_of_every_kind(defs, arrays):
    msg = from_json(defs, arrays, {})
    assert msg == default_message(defs, arrays)
    assert msg['bools'] == [] and msg['strings'] == [] and msg['f64'] == []
    assert msg['u8'] == b'' and msg['chars'] == b'' and msg['octets'] == []
    assert msg['fixed'] == [0.0, 0.0, 0.0]
    assert msg['fixed_bytes'] == b'\x00\x00\x00\x00'
    assert msg['points'] == [{'x': 0.0, 'y': 0.0, 'z': 0.0}] * 2
    assert (msg['short'], msg['b'], msg['c'], msg['small'], msg['big'], msg['single']) == ('', 0, 0, 0, 0, 0.0)


def test_default_containers_are_fresh_objects(defs):
    imu = defs.msg('sensor_msgs/msg/Imu')
    a, b = default_message(defs, imu), default_message(defs, imu)
    assert a['orientation_covariance'] == [0.0] * 9
    a['orientation_covariance'][0] = 1.0
    a['header']['frame_id'] = 'x'
    assert b['orientation_covariance'][0] == 0.0 and b['header']['frame_id'] == ''
    c, d = from_json(defs, imu, {}), from_json(defs, imu, {})
    assert c['header'] is not d['header'] and c['orientation_covariance'] is not d['orientation_covariance']


def test_header_and_camera_info_defaults(defs):
    info = from_json(defs, defs.msg('sensor_msgs/CameraInfo'), {'width': 640})
    assert info['width'] == 640 and info['k'] == [0.0] * 9 and info['d'] == [] and info['distortion_model'] == ''
    assert info['header'] == {'stamp': {'sec': 0, 'nanosec': 0}, 'frame_id': ''}
    assert info['roi']['do_rectify'] is False


def test_empty_message(defs):
    empty = defs.msg('std_msgs/msg/Empty')
    assert empty.fields == ()
    assert from_json(defs, empty, {}) == {}
    assert conv_error(defs, 'std_msgs/Empty', {'x': 1}).path == 'x'


# --- scalars ------------------------------------------------------------------------------------


def test_quaternion_defaults_to_identity_as_in_its_msg_file(defs):
    pose = from_json(defs, defs.msg('geometry_msgs/Pose'), {'position': {'x': 1}})
    assert pose['orientation'] == {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}
    assert from_cdr(defs, 'geometry_msgs/Pose', to_cdr(defs, 'geometry_msgs/Pose', {}))['orientation']['w'] == 1.0


def test_numeric_subclasses_are_accepted(defs, arrays):
    import enum

    import numpy as np

    class Mode(enum.IntEnum):
        FAST = 3
    out = from_json(defs, arrays, {'small': Mode.FAST, 'big': np.uint64(7), 'single': np.float32(0.5),
                                   'i32': [np.int32(1), 2], 'f64': [np.float64(1.5), 2]})
    assert (out['small'], out['big'], out['single'], out['i32'], out['f64']) == (3, 7, 0.5, [1, 2], [1.5, 2.0])
    assert type(out['small']) is int and type(out['big']) is int and type(out['f64'][0]) is float


def test_floats_accept_ints_and_null(defs):
    v3 = defs.msg('geometry_msgs/Vector3')
    out = from_json(defs, v3, {'x': 1, 'y': None, 'z': -2.5})
    assert out['x'] == 1.0 and type(out['x']) is float and math.isnan(out['y']) and out['z'] == -2.5


@pytest.mark.parametrize(('value', 'message', 'path'), [
    ({'linear': {'x': 'fast'}}, "field 'linear.x' must be a number, got string", 'linear.x'),
    ({'linear': {'x': True}}, "field 'linear.x' must be a number, got boolean", 'linear.x'),
    ({'linear': {'x': [1]}}, "field 'linear.x' must be a number, got array", 'linear.x'),
    ({'linear': {'q': 1}}, "unknown field 'linear.q' (geometry_msgs/msg/Vector3 has no such field)", 'linear.q'),
    ({'speed': 1}, "unknown field 'speed' (geometry_msgs/msg/Twist has no such field)", 'speed'),
    ({'linear': 5}, "field 'linear' must be an object, got number", 'linear'),
    ({'linear': None}, "field 'linear' must be an object, got null", 'linear'),
    ([], 'message must be an object, got array', ''),
    ('x', 'message must be an object, got string', ''),
])
def test_twist_errors_name_the_field_path(defs, value, message, path):
    err = conv_error(defs, 'geometry_msgs/Twist', value)
    assert (err.message, err.path) == (message, path)
    assert isinstance(err, ProtocolError) and err.level == 'error'


def test_error_path_prefix(defs):
    with pytest.raises(ConversionError) as info:
        from_json(defs, defs.msg('geometry_msgs/Twist'), {'linear': {'x': 'a'}}, path='msg')
    assert info.value.path == 'msg.linear.x' and "'msg.linear.x'" in info.value.message
    with pytest.raises(ConversionError) as info:
        from_json(defs, defs.msg('geometry_msgs/Twist'), 3, path='msg')
    assert info.value.message == "field 'msg' must be an object, got number"


@pytest.mark.parametrize(('field', 'value', 'message'), [
    ('small', 128, "field 'small' must be an int8 (-128..127), got 128"),
    ('small', -129, "field 'small' must be an int8 (-128..127), got -129"),
    ('big', -1, "field 'big' must be a uint64 (0..18446744073709551615), got -1"),
    ('big', 2**64, "field 'big' must be a uint64 (0..18446744073709551615), got 18446744073709551616"),
    ('b', 256, "field 'b' must be a byte (0..255), got 256"),
    ('c', -1, "field 'c' must be a char (0..255), got -1"),
    ('small', 1.0, "field 'small' must be an integer, got number"),
    ('small', True, "field 'small' must be an integer, got boolean"),
    ('small', '1', "field 'small' must be an integer, got string"),
    ('single', 1e39, "field 'single' is out of range for float32, got 1e+39"),
    ('single', 10**400, "field 'single' is out of range for float64, got an integer of 1329 bits"),
    ('short', 'abcdef', "field 'short' must be at most 5 characters, got 6"),
    ('short', 5, "field 'short' must be a string, got number"),
])
def test_scalar_range_and_type_errors(defs, field, value, message):
    err = conv_error(defs, 'rosgate_test/Arrays', {field: value})
    assert (err.message, err.path) == (message, field)


def test_scalar_limits_accepted(defs, arrays):
    out = from_json(defs, arrays, {'small': -128, 'big': 2**64 - 1, 'b': 255, 'c': 0, 'single': 3.4e38,
                                   'short': 'abcde'})
    assert (out['small'], out['big'], out['b'], out['single'], out['short']) == (-128, 2**64 - 1, 255, 3.4e38,
                                                                                 'abcde')
    assert math.isinf(from_json(defs, arrays, {'single': math.inf})['single'])


def test_int64_range(defs):
    req = defs.msg('example_interfaces/srv/AddTwoInts_Request')
    assert from_json(defs, req, {'a': 2**63 - 1, 'b': -(2**63)}) == {'a': 2**63 - 1, 'b': -(2**63)}
    assert conv_error(defs, 'example_interfaces/srv/AddTwoInts_Request', {'a': 2**63}).path == 'a'


def test_bool_and_string_types(defs):
    setbool = defs.msg('std_srvs/srv/SetBool_Request')
    assert from_json(defs, setbool, {'data': True}) == {'data': True}
    assert conv_error(defs, 'std_srvs/srv/SetBool_Request', {'data': 1}).message == \
        "field 'data' must be a boolean, got number"
    assert conv_error(defs, 'std_msgs/String', {'data': None}).message == "field 'data' must be a string, got null"


# --- time ---------------------------------------------------------------------------------------


def test_time_accepts_sec_nanosec_and_ros1_secs_nsecs(defs):
    header = defs.msg('std_msgs/Header')
    assert from_json(defs, header, {'stamp': {'sec': 5, 'nanosec': 7}})['stamp'] == {'sec': 5, 'nanosec': 7}
    assert from_json(defs, header, {'stamp': {'secs': 5, 'nsecs': 7}})['stamp'] == {'sec': 5, 'nanosec': 7}
    assert from_json(defs, header, {'stamp': {'secs': 5}})['stamp'] == {'sec': 5, 'nanosec': 0}
    dur = from_json(defs, defs.msg('builtin_interfaces/Duration'), {'secs': -1, 'nsecs': 500})
    assert dur == {'sec': -1, 'nanosec': 500}
    assert wire(from_json(defs, header, {'stamp': {'secs': 1}})) == {'stamp': {'sec': 1, 'nanosec': 0},
                                                                   'frame_id': ''}


def test_time_errors(defs):
    err = conv_error(defs, 'std_msgs/Header', {'stamp': {'secs': 1, 'when': 2}})
    assert err.path == 'stamp.when'
    err = conv_error(defs, 'std_msgs/Header', {'stamp': {'nsecs': 2**32}})
    assert err.message == "field 'stamp.nanosec' must be a uint32 (0..4294967295), got 4294967296"


# --- float arrays and NaN -----------------------------------------------------------------------


def test_nan_and_inf_go_out_as_null_in_scalars_and_arrays(defs):
    js = defs.msg('sensor_msgs/JointState')
    msg = from_json(defs, js, {'position': [1.5, None, 2], 'velocity': [math.nan, math.inf, -math.inf]})
    assert math.isnan(msg['position'][1]) and msg['position'][2] == 2.0
    assert wire(msg)['position'] == [1.5, None, 2.0]
    assert wire(msg)['velocity'] == [None, None, None]
    scan = defs.msg('sensor_msgs/LaserScan')
    out = from_json(defs, scan, {'range_max': math.inf, 'ranges': [0.5, math.inf, math.nan], 'intensities': [1]})
    text = dumps({'op': 'publish', 'topic': '/scan', 'msg': out})
    assert b'NaN' not in text and b'Infinity' not in text
    assert orjson.loads(text)['msg']['range_max'] is None
    assert orjson.loads(text)['msg']['ranges'] == [0.5, None, None]
    assert orjson.loads(text)['msg']['intensities'] == [1.0]


@ROUND
@given(values=st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.none(),
                                 st.integers(-2**53, 2**53)), max_size=30))
def test_float_arrays_round_trip_through_json(defs, values):
    js = defs.msg('sensor_msgs/JointState')
    text = dumps(from_json(defs, js, {'position': values}))
    again = from_json(defs, js, orjson.loads(text))['position']
    expected = [None if x is None or (isinstance(x, float) and not math.isfinite(x)) else float(x)
                for x in values]
    assert [None if math.isnan(x) else x for x in again] == expected


def test_float_arrays_from_javascript_whole_numbers(defs, arrays):
    out = from_json(defs, arrays, {'f64': [0, 1, -2], 'f32': [0, 1.5, None, math.inf]})
    assert out['f64'] == [0.0, 1.0, -2.0] and all(type(x) is float for x in out['f64'])
    assert out['f32'][:2] == [0.0, 1.5] and math.isnan(out['f32'][2]) and out['f32'][3] == math.inf
    floats = [0.25] * 10
    assert from_json(defs, arrays, {'f64': floats})['f64'] is floats  # already right: kept, not copied


def test_float_array_element_errors_name_the_index(defs):
    err = conv_error(defs, 'sensor_msgs/JointState', {'position': [1.0, 2.0, 'x']})
    assert (err.message, err.path) == ("field 'position[2]' must be a number, got string", 'position[2]')
    assert conv_error(defs, 'sensor_msgs/JointState', {'position': [True]}).path == 'position[0]'
    assert conv_error(defs, 'sensor_msgs/JointState', {'position': 1.0}).message == \
        "field 'position' must be an array, got number"
    err = conv_error(defs, 'rosgate_test/Arrays', {'f32': [1.0, 1e39]})
    assert err.message == "field 'f32[1]' is out of range for float32, got 1e+39"


def test_fixed_and_bounded_arrays(defs):
    imu = defs.msg('sensor_msgs/Imu')
    assert from_json(defs, imu, {'orientation_covariance': list(range(9))})['orientation_covariance'] == \
        [float(i) for i in range(9)]
    err = conv_error(defs, 'sensor_msgs/Imu', {'orientation_covariance': [0.0] * 8})
    assert (err.message, err.path) == ("field 'orientation_covariance' must have exactly 9 elements, got 8",
                                       'orientation_covariance')
    assert conv_error(defs, 'rosgate_test/Arrays', {'few': [1, 2, 3, 4]}).message == \
        "field 'few' must have at most 3 elements, got 4"
    assert conv_error(defs, 'rosgate_test/Arrays', {'tags': ['ab', 'abc']}).message == \
        "field 'tags[1]' must be at most 2 characters, got 3"
    assert conv_error(defs, 'rosgate_test/Arrays', {'fixed_bytes': 'AAAA'}).message == \
        "field 'fixed_bytes' must have exactly 4 elements, got 3"
    assert conv_error(defs, 'rosgate_test/Arrays', {'points': [{}]}).path == 'points'


def test_integer_bool_and_string_arrays(defs, arrays):
    out = from_json(defs, arrays, {'i8': [-128, 127], 'u64': [0, 2**64 - 1], 'bools': [True, False],
                                   'strings': ['a', ''], 'few': [1, 2, 3], 'tags': ['ab']})
    assert (out['i8'], out['u64'], out['bools'], out['strings']) == ([-128, 127], [0, 2**64 - 1], [True, False],
                                                                     ['a', ''])
    for field, value, message in [
        ('i8', [0, 128], "field 'i8[1]' must be an int8 (-128..127), got 128"),
        ('u16', [1, -1], "field 'u16[1]' must be a uint16 (0..65535), got -1"),
        ('i32', [1, 2.0], "field 'i32[1]' must be an integer, got number"),
        ('i64', [False], "field 'i64[0]' must be an integer, got boolean"),
        ('bools', [True, 0], "field 'bools[1]' must be a boolean, got number"),
        ('strings', ['a', None], "field 'strings[1]' must be a string, got null"),
    ]:
        assert conv_error(defs, 'rosgate_test/Arrays', {field: value}).message == message


def test_message_arrays_name_index_and_field(defs):
    poses = defs.msg('geometry_msgs/PoseArray')
    out = from_json(defs, poses, {'poses': [{}, {'position': {'x': 1}}]})
    assert out['poses'][1]['position'] == {'x': 1.0, 'y': 0.0, 'z': 0.0}
    assert out['poses'][0]['orientation'] == {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}  # as in Quaternion.msg
    err = conv_error(defs, 'geometry_msgs/PoseArray', {'poses': [{}, {'position': {'q': 1}}]})
    assert (err.message, err.path) == (
        "unknown field 'poses[1].position.q' (geometry_msgs/msg/Point has no such field)", 'poses[1].position.q')
    err = conv_error(defs, 'geometry_msgs/PoseArray', {'poses': [{}, 3]})
    assert err.message == "field 'poses[1]' must be an object, got number"


# --- byte arrays --------------------------------------------------------------------------------


def test_uint8_array_base64_round_trip(defs):
    img = defs.msg('sensor_msgs/Image')
    raw = bytes(range(256)) * 3
    b64 = base64.b64encode(raw).decode()
    msg = from_json(defs, img, {'height': 1, 'width': 768, 'encoding': 'mono8', 'step': 768, 'data': b64})
    assert msg['data'] == raw
    assert wire(msg)['data'] == b64
    assert from_json(defs, img, wire(msg)) == msg


def test_uint8_array_accepts_list_of_ints_and_bytes(defs):
    img = defs.msg('sensor_msgs/Image')
    assert from_json(defs, img, {'data': [0, 1, 255]})['data'] == b'\x00\x01\xff'
    assert from_json(defs, img, {'data': b'\x07'})['data'] == b'\x07'  # CBOR byte strings
    assert wire(from_json(defs, img, {'data': [0, 1, 255]}))['data'] == 'AAH/'


@pytest.mark.parametrize(('value', 'message'), [
    ([0, 256], "field 'data[1]' must be a uint8 (0..255), got 256"),
    ([0, 'a'], "field 'data[1]' must be an integer, got string"),
    ('not base64!', "field 'data' must be a base64 string or an array of integers 0..255, got a string that is "
                    'not base64'),
    (5, "field 'data' must be a base64 string or an array of integers 0..255, got number"),
])
def test_uint8_array_errors(defs, value, message):
    err = conv_error(defs, 'sensor_msgs/Image', {'data': value})
    assert err.message.startswith(message) and err.path.startswith('data')


def test_char_array_is_base64_too(defs, arrays):
    msg = from_json(defs, arrays, {'chars': 'aGk='})
    assert msg['chars'] == b'hi' and wire(msg)['chars'] == 'aGk='
    assert from_json(defs, arrays, {'chars': [104, 105]})['chars'] == b'hi'


def test_byte_array_is_a_list_of_ints_like_rclpy(defs):
    pv = defs.msg('rcl_interfaces/msg/ParameterValue')
    msg = from_json(defs, pv, {'type': 5, 'byte_array_value': [0, 200, 255]})
    assert msg['byte_array_value'] == [0, 200, 255] and wire(msg)['byte_array_value'] == [0, 200, 255]
    assert from_json(defs, pv, {'byte_array_value': 'AMj/'})['byte_array_value'] == [0, 200, 255]
    assert conv_error(defs, 'rcl_interfaces/msg/ParameterValue', {'byte_array_value': [300]}).path == \
        'byte_array_value[0]'


@ROUND
@given(raw=st.binary(max_size=300))
def test_uint8_base64_round_trip_property(defs, raw):
    img = defs.msg('sensor_msgs/CompressedImage')
    text = dumps(from_json(defs, img, {'data': list(raw)}))
    assert from_json(defs, img, orjson.loads(text))['data'] == raw


# --- service/goal args --------------------------------------------------------------------------


def test_from_args_object_list_and_null(defs):
    req = defs.msg('example_interfaces/srv/AddTwoInts_Request')
    assert from_args(defs, req, {'a': 1, 'b': 2}) == {'a': 1, 'b': 2}
    assert from_args(defs, req, [3, 4]) == {'a': 3, 'b': 4}
    assert from_args(defs, req, [3]) == {'a': 3, 'b': 0}
    assert from_args(defs, req, None) == {'a': 0, 'b': 0}
    with pytest.raises(ConversionError) as info:
        from_args(defs, req, [1, 2, 3])
    assert info.value.message == \
        "field 'args' has 3 values but example_interfaces/srv/AddTwoInts_Request has 2 fields"
    with pytest.raises(ConversionError) as info:
        from_args(defs, req, {'a': 'x'})
    assert info.value.path == 'args.a'


# --- CBOR ---------------------------------------------------------------------------------------

TAGS = {'f64': (86, '<d'), 'f32': (85, '<f'), 'i8': (72, '<b'), 'i16': (77, '<h'), 'u16': (69, '<H'),
        'i32': (78, '<i'), 'u32': (70, '<I'), 'i64': (79, '<q'), 'u64': (71, '<Q')}
SAMPLES = {'f64': [1.5, -2.25, math.inf], 'f32': [0.5, -8.0], 'i8': [-128, 0, 127], 'i16': [-32768, 32767],
           'u16': [0, 65535], 'i32': [-(2**31), 2**31 - 1], 'u32': [0, 2**32 - 1], 'i64': [-(2**63), 2**63 - 1],
           'u64': [0, 2**64 - 1]}


def test_cbor_typed_arrays_decode_back(defs, arrays):
    msg = from_json(defs, arrays, {**SAMPLES, 'u8': 'AAH/', 'chars': 'aGk=', 'octets': [1, 255],
                                   'bools': [True], 'strings': ['s'], 'fixed': [1, 2, 3],
                                   'points': [{'x': 1}, {}]})
    frame = encode_cbor({'op': 'publish', 'topic': '/a', 'msg': to_cbor(arrays, msg, defs)})
    out = cbor2.loads(frame)['msg']
    for field, (tag, fmt) in TAGS.items():
        assert out[field].tag == tag, field
        count = len(out[field].value) // struct.calcsize(fmt)
        assert list(struct.unpack(fmt[0] + fmt[1] * count, out[field].value)) == SAMPLES[field], field
    assert out['fixed'].tag == 86 and struct.unpack('<3d', out['fixed'].value) == (1.0, 2.0, 3.0)
    assert out['u8'] == b'\x00\x01\xff' and out['chars'] == b'hi' and out['octets'] == b'\x01\xff'
    assert out['fixed_bytes'] == b'\x00' * 4
    assert out['bools'] == [True] and out['strings'] == ['s']
    assert out['points'] == [{'x': 1.0, 'y': 0.0, 'z': 0.0}, {'x': 0.0, 'y': 0.0, 'z': 0.0}]
    assert out['durations'] == []
    assert msg['f64'] == SAMPLES['f64']  # to_cbor left the message itself alone


def test_cbor_keeps_nan_and_nested_arrays(defs):
    js = defs.msg('sensor_msgs/JointState')
    msg = from_json(defs, js, {'position': [None, 1.0]})
    out = cbor2.loads(encode_cbor(to_cbor(js, msg, defs)))
    values = struct.unpack('<2d', out['position'].value)
    assert math.isnan(values[0]) and values[1] == 1.0
    path = defs.msg('nav_msgs/Path')
    nested = to_cbor(path, from_json(defs, path, {'poses': [{'pose': {'position': {'x': 1}}}]}), defs)
    assert nested['poses'][0]['pose']['position']['x'] == 1.0


def test_cbor_leaves_messages_without_arrays_untouched(defs):
    twist = defs.msg('geometry_msgs/Twist')
    msg = from_json(defs, twist, {})
    assert to_cbor(twist, msg, defs) is msg


def test_cbor_packs_arrays_given_as_numpy_and_array(defs):
    import array

    import numpy as np
    js = defs.msg('sensor_msgs/JointState')
    msg = {'header': {'stamp': {'sec': 0, 'nanosec': 0}, 'frame_id': ''}, 'name': [],
           'position': np.array([1.0, 2.0]), 'velocity': array.array('d', [3.0]), 'effort': [4.0]}
    out = cbor2.loads(encode_cbor(to_cbor(js, msg, defs)))
    assert struct.unpack('<2d', out['position'].value) == (1.0, 2.0)
    assert struct.unpack('<d', out['velocity'].value) == (3.0,)


def test_image_as_cbor_keeps_bytes(defs):
    img = defs.msg('sensor_msgs/Image')
    raw = bytes(range(256)) * 10
    msg = from_json(defs, img, {'data': base64.b64encode(raw).decode(), 'width': 2560, 'height': 1})
    out = cbor2.loads(encode_cbor({'op': 'publish', 'msg': to_cbor(img, msg, defs)}))
    assert out['msg']['data'] == raw and out['msg']['width'] == 2560


# --- CDR ----------------------------------------------------------------------------------------


def test_cdr_twist_bytes_match_the_ros2_wire_format(defs):
    msg = from_json(defs, defs.msg('geometry_msgs/Twist'), {'linear': {'x': 1, 'y': 2}, 'angular': {'z': -3}})
    data = to_cdr(defs, 'geometry_msgs/Twist', msg)
    assert data == b'\x00\x01\x00\x00' + struct.pack('<6d', 1, 2, 0, 0, 0, -3)
    assert from_cdr(defs, 'geometry_msgs/msg/Twist', data) == msg


def test_cdr_round_trip_of_every_kind(defs, arrays):
    msg = from_json(defs, arrays, {**SAMPLES, 'u8': 'AAH/', 'chars': 'aGk=', 'octets': [0, 128, 255],
                                   'bools': [True, False], 'strings': ['x', 'yz'], 'fixed': [1, 2, 3],
                                   'fixed_bytes': [1, 2, 3, 4], 'short': 'hey', 'few': [7], 'tags': ['ab'],
                                   'points': [{'x': 1}, {'z': 2}], 'durations': [{'sec': 1, 'nanosec': 2}],
                                   'b': 200, 'c': 65, 'small': -5, 'big': 2**64 - 1, 'single': 0.5})
    back = from_cdr(defs, 'rosgate_test/msg/Arrays', to_cdr(defs, 'rosgate_test/msg/Arrays', msg))
    assert back == msg
    assert type(back['u8']) is bytes and type(back['octets']) is list and type(back['f64']) is list
    # rosbags reads the same bytes into its own objects, field for field
    obj = defs.typestore.deserialize_cdr(to_cdr(defs, 'rosgate_test/Arrays', msg), 'rosgate_test/msg/Arrays')
    assert obj.u8.tobytes() == b'\x00\x01\xff' and obj.strings == ['x', 'yz'] and obj.points[1].z == 2.0


def test_cdr_fills_defaults_and_handles_services_and_empty(defs):
    data = to_cdr(defs, 'example_interfaces/srv/AddTwoInts_Request', {'a': 5})
    assert from_cdr(defs, 'example_interfaces/srv/AddTwoInts_Request', data) == {'a': 5, 'b': 0}
    assert from_cdr(defs, 'std_msgs/Empty', to_cdr(defs, 'std_msgs/Empty', {})) == {}
    goal = from_cdr(defs, 'example_interfaces/action/Fibonacci_Feedback',
                    to_cdr(defs, 'example_interfaces/action/Fibonacci_Feedback', {'sequence': [0, 1, 1, 2]}))
    assert goal == {'sequence': [0, 1, 1, 2]}


def test_cdr_image(defs):
    img = defs.msg('sensor_msgs/Image')
    raw = bytes(range(256)) * 12
    msg = from_json(defs, img, {'header': {'frame_id': 'cam', 'stamp': {'sec': 3}}, 'height': 16, 'width': 64,
                                'encoding': 'rgb8', 'step': 192, 'data': base64.b64encode(raw).decode()})
    assert from_cdr(defs, 'sensor_msgs/Image', to_cdr(defs, 'sensor_msgs/Image', msg)) == msg


def test_cbor_raw_frame_carries_cdr_bytes_rosbags_can_read(defs):
    scan = defs.msg('sensor_msgs/LaserScan')
    msg = from_json(defs, scan, {'header': {'frame_id': 'laser'}, 'angle_max': 3.14, 'ranges': [1.0, 2.5, math.inf]})
    frame = encode_cbor({'op': 'publish', 'topic': '/scan',
                         'msg': {'secs': 12, 'nsecs': 34, 'bytes': to_cdr(defs, 'sensor_msgs/LaserScan', msg)}})
    out = cbor2.loads(frame)
    assert (out['op'], out['topic'], out['msg']['secs'], out['msg']['nsecs']) == ('publish', '/scan', 12, 34)
    obj = defs.typestore.deserialize_cdr(out['msg']['bytes'], 'sensor_msgs/msg/LaserScan')
    assert obj.header.frame_id == 'laser' and obj.ranges.tolist() == [1.0, 2.5, math.inf]
    assert obj.angle_max == pytest.approx(3.14)


def test_cdr_errors_are_conversion_errors(defs):
    with pytest.raises(ConversionError):
        to_cdr(defs, 'sensor_msgs/Imu', {'orientation_covariance': [1.0]})
    with pytest.raises(ConversionError):
        from_cdr(defs, 'geometry_msgs/Twist', b'\x00\x01\x00\x00\x01')
    with pytest.raises(ConversionError):
        from_cdr(defs, 'geometry_msgs/Twist', b'garbage!')


@ROUND
@given(names=st.lists(st.text(max_size=8), max_size=4),
       position=st.lists(st.floats(allow_nan=False, width=64), max_size=6),
       stamp=st.tuples(st.integers(-(2**31), 2**31 - 1), st.integers(0, 2**32 - 1)))
def test_cdr_round_trip_property(defs, names, position, stamp):
    js = defs.msg('sensor_msgs/JointState')
    msg = from_json(defs, js, {'header': {'stamp': {'sec': stamp[0], 'nanosec': stamp[1]}}, 'name': names,
                               'position': position})
    assert from_cdr(defs, 'sensor_msgs/JointState', to_cdr(defs, 'sensor_msgs/JointState', msg)) == msg
