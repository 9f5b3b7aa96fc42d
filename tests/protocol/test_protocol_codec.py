"""Wire encodings: JSON, CBOR, png, outgoing fragments and incoming reassembly."""

from __future__ import annotations

import array
import base64
import io
import json
import math
import random
import struct

import cbor2
import numpy as np
import orjson
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from protocol.codec import (MESSAGE_COST, PIECE_COST, Reassembler, decode_binary, decode_png, decode_text, dumps, encode_cbor, fragment_ops,
                            png_ops)
from protocol.errors import ProtocolError
from protocol.ops import Fragment

# --- JSON ---------------------------------------------------------------------------------------


def test_decode_text_accepts_str_and_bytes():
    assert decode_text('{"op":"publish","msg":{"x":1.5}}') == {'op': 'publish', 'msg': {'x': 1.5}}
    assert decode_text(b'{"op":"x"}') == {'op': 'x'}


@pytest.mark.parametrize(('data', 'start'), [
    ('{"op": "publish"', 'invalid JSON'),
    ('', 'invalid JSON'),
    ('not json at all', 'invalid JSON'),
    (b'{"op": "\xff"}', 'invalid JSON'),
    ('[1, 2]', 'expected a JSON object, got array'),
    ('"op"', 'expected a JSON object, got string'),
    ('null', 'expected a JSON object, got null'),
])
def test_decode_text_rejects_garbage(data, start):
    with pytest.raises(ProtocolError) as info:
        decode_text(data)
    assert info.value.message.startswith(start)
    assert info.value.level == 'error'


def test_decode_text_accepts_python_nan_tokens():
    # roslibpy encodes with json.dumps, which writes NaN/Infinity for non-finite floats
    frame = json.dumps({'op': 'publish', 'msg': {'a': math.nan, 'b': [math.inf, -math.inf]}})
    obj = decode_text(frame)
    assert math.isnan(obj['msg']['a']) and obj['msg']['b'] == [math.inf, -math.inf]


def test_dumps_maps_nan_and_inf_to_null_everywhere():
    obj = {'a': math.nan, 'b': [1.0, math.inf, -math.inf, math.nan], 'c': {'d': [[math.nan]]}, 'e': (math.inf,)}
    assert orjson.loads(dumps(obj)) == {'a': None, 'b': [1.0, None, None, None], 'c': {'d': [[None]]},
                                        'e': [None]}
    assert b'NaN' not in dumps(obj) and b'Infinity' not in dumps(obj)


def test_dumps_arrays_from_numpy_and_array_module():
    obj = {'np64': np.array([1.5, np.nan, np.inf]), 'np32': np.array([0.5, np.nan], dtype=np.float32),
           'ints': np.array([1, -2], dtype=np.int16), 'arr': array.array('d', [2.0, math.nan]),
           'arr_i': array.array('i', [3, 4]), 'scalar': np.float32(1.5)}
    assert orjson.loads(dumps(obj)) == {'np64': [1.5, None, None], 'np32': [0.5, None], 'ints': [1, -2],
                                        'arr': [2.0, None], 'arr_i': [3, 4], 'scalar': 1.5}


def test_dumps_bytes_as_base64():
    raw = bytes(range(256))
    out = orjson.loads(dumps({'data': raw, 'ba': bytearray(b'\x01\x02'), 'mv': memoryview(b'xyz')}))
    assert base64.b64decode(out['data']) == raw
    assert out['ba'] == 'AQI=' and out['mv'] == 'eHl6'


def test_dumps_refuses_unknown_objects():
    with pytest.raises(TypeError):
        dumps({'x': object()})


def test_dumps_is_compact_utf8():
    assert dumps({'op': 'status', 'msg': 'é'}) == '{"op":"status","msg":"é"}'.encode()


# --- CBOR ---------------------------------------------------------------------------------------


def test_decode_binary_map_and_typed_arrays():
    tags = {'f': cbor2.CBORTag(86, struct.pack('<2d', 1.5, -2)), 'i': cbor2.CBORTag(78, struct.pack('<3i', -1, 0, 7)),
            'u': cbor2.CBORTag(71, struct.pack('<Q', 2**64 - 1))}
    payload = cbor2.dumps({'op': 'publish', 'msg': {'data': b'\x00\x01', **tags}})
    assert decode_binary(payload) == {'op': 'publish', 'msg': {'data': b'\x00\x01', 'f': [1.5, -2.0],
                                                               'i': [-1, 0, 7], 'u': [2**64 - 1]}}


@pytest.mark.parametrize(('data', 'start'), [
    (b'\xff\x00garbage', 'invalid CBOR'),
    (b'', 'invalid CBOR'),
    (cbor2.dumps({'op': 'x'})[:-1], 'invalid CBOR'),
    (cbor2.dumps({'f': cbor2.CBORTag(86, b'\x00' * 7)}), 'invalid CBOR'),
    (cbor2.dumps([1, 2]), 'expected a CBOR map, got array'),
    (cbor2.dumps('op'), 'expected a CBOR map, got string'),
])
def test_decode_binary_rejects_garbage(data, start):
    with pytest.raises(ProtocolError) as info:
        decode_binary(data)
    assert info.value.message.startswith(start)


def test_encode_cbor_keeps_bytes_and_tags_arrays():
    tag = cbor2.CBORTag(85, struct.pack('<2f', 1.0, 2.0))
    out = cbor2.loads(encode_cbor({'op': 'publish', 'msg': {'data': b'\x00\xff', 'f': tag,
                                                            'a': array.array('H', [1, 65535]),
                                                            'n': np.array([1.0, np.nan]), 'nan': math.nan}}))
    msg = out['msg']
    assert msg['data'] == b'\x00\xff'
    assert msg['f'] == tag
    assert msg['a'] == [1, 65535]  # array.array is a plain CBOR list; to_cbor makes typed arrays
    assert msg['n'].tag == 86 and struct.unpack('<d', msg['n'].value[:8]) == (1.0,)
    assert math.isnan(struct.unpack('<d', msg['n'].value[8:])[0])
    assert math.isnan(msg['nan'])


def test_encode_then_decode_binary_round_trip():
    obj = {'op': 'publish', 'topic': '/t', 'msg': {'x': [1, 2, 3], 'b': b'abc', 's': 'é', 'n': None}}
    assert decode_binary(encode_cbor(obj)) == obj


# --- png ----------------------------------------------------------------------------------------


def png_pixels(data_b64: str) -> tuple[Image.Image, bytes]:
    img = Image.open(io.BytesIO(base64.b64decode(data_b64)))
    return img, img.tobytes()


@pytest.mark.parametrize('length', [0, 1, 2, 3, 4, 100, 1001, 30000])
def test_png_is_rosbridge_layout_and_round_trips(length):
    obj = {'op': 'publish', 'topic': '/t', 'msg': {'data': 'x' * max(0, length - 44)}}
    frame = dumps(obj)
    [op] = png_ops(frame)
    assert set(op) == {'op', 'data'} and op['op'] == 'png'
    img, pixels = png_pixels(op['data'])
    assert img.format == 'PNG' and img.mode == 'RGB'
    width = max(1, math.floor(math.sqrt(len(frame) / 3)))
    assert img.width == width and img.height == max(1, math.ceil(len(frame) / 3 / width))
    assert pixels.startswith(frame) and set(pixels[len(frame):]) <= {ord('\n')}
    assert decode_png(op['data']) == obj


def test_png_ops_split_like_fragments_when_too_long():
    obj = {'op': 'publish', 'topic': '/t', 'msg': {'data': bytes(random.Random(1).randbytes(3000)).hex()}}
    whole = png_ops(dumps(obj))[0]['data']
    pieces = png_ops(dumps(obj), max_size=1000, id='png:1')
    assert len(pieces) == math.ceil(len(whole) / 1000) > 1
    assert [p['num'] for p in pieces] == list(range(len(pieces)))
    assert all(p['op'] == 'png' and p['id'] == 'png:1' and p['total'] == len(pieces) for p in pieces)
    assert all(len(p['data']) <= 1000 for p in pieces)
    assert decode_png(''.join(p['data'] for p in pieces)) == obj
    assert png_ops(dumps(obj), max_size=10**9, id='x') == [{'op': 'png', 'data': whole, 'id': 'x'}]


def test_decode_png_rejects_garbage_and_huge_images():
    for data in ('not base64 !', base64.b64encode(b'not a png').decode()):
        with pytest.raises(ProtocolError) as info:
            decode_png(data)
        assert info.value.message.startswith('png: cannot decode') and info.value.op == 'png'
    buf = io.BytesIO()
    Image.new('RGB', (2000, 2000)).save(buf, 'png')
    with pytest.raises(ProtocolError) as info:
        decode_png(base64.b64encode(buf.getvalue()).decode(), max_bytes=2**20)
    assert 'too large' in info.value.message


# --- outgoing fragments -------------------------------------------------------------------------


def test_fragment_ops_leave_small_frames_alone():
    assert fragment_ops(b'{"op":"x"}', 10, 'id') == []
    assert fragment_ops('{"op":"x"}', 100, 'id') == []


def test_fragment_ops_split_in_rosbridge_shape():
    frame = dumps({'op': 'publish', 'topic': '/t', 'msg': {'data': 'abcdefghij' * 10}})
    frags = fragment_ops(frame, 30, 'publish:/t:1')
    total = math.ceil(len(frame) / 30)
    assert len(frags) == total
    for i, f in enumerate(frags):
        assert f == {'op': 'fragment', 'id': 'publish:/t:1', 'data': frame.decode()[i * 30:(i + 1) * 30],
                     'num': i, 'total': total}
    assert ''.join(f['data'] for f in frags).encode() == frame


def test_fragment_ops_rejects_bad_size():
    with pytest.raises(ValueError):
        fragment_ops('{"op":"x"}', 0, 'id')


@settings(max_examples=60, deadline=None, database=None)
@given(text=st.text(min_size=1, max_size=400), size=st.integers(1, 50), seed=st.integers(0, 1000))
def test_fragments_reassemble_in_any_order(text, size, seed):
    frame = dumps({'op': 'publish', 'topic': '/t', 'msg': {'data': text}})
    frags = fragment_ops(frame, size, 'x') or [{'op': 'fragment', 'id': 'x', 'data': frame.decode(),
                                               'num': 0, 'total': 1}]
    random.Random(seed).shuffle(frags)
    r = Reassembler()
    results = [r.add(Fragment(f['id'], f['data'], f['num'], f['total']), now=0.0) for f in frags]
    assert results[:-1] == [None] * (len(frags) - 1)
    assert results[-1] == {'op': 'publish', 'topic': '/t', 'msg': {'data': text}}
    assert len(r) == 0 and r.pending_bytes == 0


# --- incoming reassembly ------------------------------------------------------------------------


def pieces(obj: dict, size: int, fid: str = 'f') -> list[Fragment]:
    return [Fragment(f['id'], f['data'], f['num'], f['total']) for f in fragment_ops(dumps(obj), size, fid)]


def test_reassembler_interleaved_ids_and_duplicates():
    a, b = {'op': 'publish', 'topic': '/a', 'msg': {}}, {'op': 'publish', 'topic': '/b', 'msg': {}}
    fa, fb = pieces(a, 7, 'a'), pieces(b, 7, 'b')
    r = Reassembler()
    assert r.add(fa[0], 0) is None
    assert r.add(fa[0], 0) is None  # a repeated piece replaces the earlier copy
    assert r.add(fb[0], 0) is None
    assert len(r) == 2
    out = [r.add(f, 1) for f in fa[1:] + fb[1:]]
    assert [o for o in out if o is not None] == [a, b]
    assert r.pending_bytes == 0


def test_reassembler_rejects_inconsistent_fragments():
    r = Reassembler()
    r.add(Fragment('f', '{"op"', 0, 3), 0)
    with pytest.raises(ProtocolError) as info:
        r.add(Fragment('f', ':"x"}', 1, 2), 0)
    assert (info.value.op, info.value.id) == ('fragment', 'f')
    assert 'total changed from 3 to 2' in info.value.message
    assert len(r) == 0  # the broken message is dropped
    with pytest.raises(ProtocolError) as info:
        r.add(Fragment('g', 'x', 5, 2), 0)
    assert 'num 5 is outside 0..1' in info.value.message


def test_reassembler_reports_bad_json_inside_fragments():
    r = Reassembler()
    r.add(Fragment('f', '{"op": ', 0, 2), 0)
    with pytest.raises(ProtocolError) as info:
        r.add(Fragment('f', 'oops', 1, 2), 0)
    assert info.value.id == 'f' and 'reassembled message: invalid JSON' in info.value.message


def test_reassembler_expires_stale_messages():
    r = Reassembler(timeout=10)
    r.add(Fragment('old', 'a', 0, 2), now=0)
    r.add(Fragment('new', 'b', 0, 2), now=8)
    assert r.expire(now=9) == []
    r.add(Fragment('old', 'a', 0, 2), now=9)  # a fragment keeps its message alive
    assert r.expire(now=18.5) == ['new']
    assert r.expire(now=19.5) == ['old']
    assert len(r) == 0 and r.pending_bytes == 0
    # a late piece of an expired message starts over instead of completing garbage
    assert r.add(Fragment('old', '"}', 1, 2), now=20) is None


def test_reassembler_limits_pending_messages():
    r = Reassembler(max_messages=3)
    for i in range(3):
        r.add(Fragment(f'm{i}', 'x', 0, 2), 0)
    with pytest.raises(ProtocolError) as info:
        r.add(Fragment('m3', 'x', 0, 2), 0)
    assert 'too many incomplete messages' in info.value.message and info.value.id == 'm3'
    assert info.value.close == 1008   # a client past a bound is disconnected
    assert len(r) == 3


def test_reassembler_limits_pending_bytes():
    message = MESSAGE_COST + 1 + PIECE_COST   # a message of a one-letter id holding one empty piece
    r = Reassembler(max_bytes=2 * message + PIECE_COST + 60 + 30 + 20)
    r.add(Fragment('a', 'x' * 60, 0, 3), 0)
    r.add(Fragment('b', 'x' * 30, 0, 3), 0)
    assert r.pending_bytes == 2 * message + 90
    with pytest.raises(ProtocolError) as info:
        r.add(Fragment('a', 'x' * 21, 1, 3), 0)
    assert 'exceed' in info.value.message and info.value.close == 1008
    assert len(r) == 1 and r.pending_bytes == message + 30  # the flooding message is dropped


def test_reassembler_empty_pieces_count_their_envelope():
    """200,000 empty pieces of one message counted 0 bytes and held ~16 MB: each counts PIECE_COST."""
    limit = 10 * 2**20
    r = Reassembler(max_bytes=limit)
    stored = 0
    with pytest.raises(ProtocolError) as info:
        for num in range(200_000):
            r.add(Fragment('e', '', num, limit), 0)
            stored += 1
    assert 'exceed' in info.value.message and info.value.close == 1008
    assert 0 < stored <= limit // PIECE_COST
    assert len(r) == 0 and r.pending_bytes == 0


def test_reassembler_caps_total_by_the_message_limit():
    r = Reassembler(max_bytes=1000)
    for total in (2**31 - 1, 10**12, 1001):
        with pytest.raises(ProtocolError) as info:
            r.add(Fragment('huge', 'x', 0, total), 0)
        assert f'total {total} exceeds' in info.value.message and info.value.close == 1008
    assert len(r) == 0 and r.pending_bytes == 0
    assert r.add(Fragment('ok', '{', 0, 1000), 0) is None
