"""Hostile input at the edge: what the protocol layer refuses, and what its errors keep alive."""

from __future__ import annotations

import base64
import io
import json

import cbor2
import pytest
from PIL import Image

from protocol.codec import decode_binary, decode_text
from protocol.errors import ProtocolError
from protocol.session import Session


def only_error(items) -> ProtocolError:
    assert len(items) == 1 and isinstance(items[0], ProtocolError), items
    return items[0]


@pytest.mark.parametrize('frame, id, field', [
    ('{"op": "subscribe", "topic": "/x\\ud800", "id": "s1"}', 's1', 'topic'),
    ('{"op": "publish", "topic": "/x", "id": "p1", "msg": {"data": "a\\udc00b"}}', 'p1', 'msg.data'),
    ('{"op": "publish", "topic": "/x", "id": "p2", "msg": {"a\\ud800": 1}}', 'p2', "msg.'a\\ud800'"),
    ('{"op": "call_service", "service": "/s", "id": "c1", "args": [1, "\\ud800"]}', 'c1', 'args[1]'),
    ('{"op": "nope", "id": "a\\udc00"}', None, 'id'),
])
def test_lone_surrogates_are_refused_naming_the_field(frame, id, field):
    error = only_error(Session().receive_text(frame, 0.0))
    assert error.id == id and f"field '{field}' is not valid Unicode" in error.message
    json.dumps(error.message, ensure_ascii=False).encode('utf-8')   # the status can be written


def test_nan_tokens_still_accepted():
    assert decode_text('{"op": "publish", "topic": "/x", "msg": {"data": NaN}}')['msg']['data'] != 0


@pytest.mark.parametrize('op, field', [
    ({'op': 'subscribe', 'topic': '/x', 'id': 'b1', 'queue_length': -(10**5000)}, 'queue_length'),
    ({'op': 'subscribe', 'topic': '/x', 'id': 'b2', 'throttle_rate': 10**400}, 'throttle_rate'),
    ({'op': 'call_service', 'service': '/x', 'id': 'b3', 'timeout': 10**5000}, 'timeout'),
    ({'op': 'call_service', 'service': '/x', 'id': 'b4', 'timeout': float('inf')}, 'timeout'),
    ({'op': 'action_result', 'action': '/x', 'id': 'b5', 'status': -(10**5000)}, 'status'),
])
def test_cbor_bignums_are_refused_with_a_short_sentence(op, field):
    error = only_error(Session().receive_bytes(cbor2.dumps(op), 0.0))
    assert error.id == op['id'] and f"field '{field}'" in error.message and len(error.message) < 200


def test_bignum_ids_are_not_ids():
    error = only_error(Session().receive_bytes(cbor2.dumps({'op': 'nope', 'id': 10**5000}), 0.0))
    assert error.id is None and 'nope' in error.message


def test_errors_do_not_hold_the_frame():
    big = '{"op": "publish", "topic": "/x", "msg": {"data": "' + 'x' * 2**20 + '"'   # unterminated
    for error in (only_error(Session().receive_text(big, 0.0)),
                  only_error(Session().receive_bytes(b'\xff' + b'x' * 2**20, 0.0))):
        assert error.__context__ is None and error.__cause__ is None and error.__traceback__ is None
    with pytest.raises(ProtocolError) as info:
        decode_text(big)
    assert info.value.__context__ is None
    with pytest.raises(ProtocolError) as info:
        decode_binary(b'\xff' * 10)
    assert info.value.__context__ is None


def _png(width: int, height: int) -> str:
    buf = io.BytesIO()
    Image.new('RGB', (width, height), (32, 32, 32)).save(buf, 'png')
    return base64.b64encode(buf.getvalue()).decode()


def test_png_errors_carry_the_id():
    error = only_error(Session().receive_text('{"op": "png", "id": "T7", "data": "!!!!"}', 0.0))
    assert error.id == 'T7' and error.op == 'png'


def test_png_inflating_past_the_frame_limit_is_refused_by_its_header():
    data = _png(4700, 4700)
    assert len(data) < 200_000   # a small frame that would inflate to 66 MB
    frame = json.dumps({'op': 'png', 'id': 'big', 'data': data})
    error = only_error(Session(max_message_size=10 * 2**20).receive_text(frame, 0.0))
    assert error.id == 'big' and 'too large' in error.message
