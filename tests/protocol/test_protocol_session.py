"""The per-client Session: frames in, ops and errors out, fragments, levels, limits."""

from __future__ import annotations

import cbor2
import pytest

from protocol import ops
from protocol.codec import dumps, fragment_ops, png_ops
from protocol.errors import ProtocolError
from protocol.session import Session

SUB = {'op': 'subscribe', 'id': 'subscribe:/chatter:1', 'topic': '/chatter', 'type': 'std_msgs/String'}


def only_error(results) -> ProtocolError:
    assert len(results) == 1 and isinstance(results[0], ProtocolError), results
    return results[0]


def test_text_and_bytes_frames_become_ops():
    s = Session()
    assert s.receive_text(dumps(SUB).decode(), now=0) == [ops.Subscribe('/chatter', 'subscribe:/chatter:1',
                                                                        'std_msgs/String')]
    assert s.receive_text(dumps(SUB), now=0) == s.receive_bytes(cbor2.dumps(SUB), now=0)


@pytest.mark.parametrize('frame', ['{"op": "subscribe"', 'hello', '', '[1,2,3]', '42', '\x00\x01'])
def test_garbage_text_is_an_error_not_an_exception(frame):
    err = only_error(Session().receive_text(frame, now=0))
    assert err.level == 'error' and err.message


@pytest.mark.parametrize('frame', [b'\xff\xfe', b'', cbor2.dumps([1]), b'\x9f' * 10])
def test_garbage_binary_is_an_error(frame):
    only_error(Session().receive_bytes(frame, now=0))


def test_bad_ops_name_op_and_id():
    s = Session()
    err = only_error(s.receive_text('{"op":"subscribe","id":"s1","topic":"/t","throttle_rate":"x"}', now=0))
    assert (err.op, err.id) == ('subscribe', 's1')
    assert err.message == "subscribe: field 'throttle_rate' must be an integer, got string"
    err = only_error(s.receive_text('{"op":"dance","id":"d"}', now=0))
    assert (err.message, err.op, err.id) == ("unknown op 'dance'", 'dance', 'd')
    assert s.status(err.level, err.message, id=err.id, op=err.op) == \
        {'op': 'status', 'level': 'error', 'msg': "dance: unknown op 'dance'", 'id': 'd'}


def test_session_keeps_going_after_errors():
    s = Session()
    frames = ['nonsense', dumps({'op': 'publish', 'topic': '/t'}).decode(), dumps(SUB).decode()]
    results = [r for f in frames for r in s.receive_text(f, now=0)]
    assert [type(r) for r in results] == [ProtocolError, ProtocolError, ops.Subscribe]


def test_fragments_reassemble_into_the_op():
    s = Session()
    pub = {'op': 'publish', 'id': 'p1', 'topic': '/chatter', 'msg': {'data': 'hello ' * 50}}
    frags = fragment_ops(dumps(pub), 40, 'frag:1')
    assert len(frags) > 3
    for f in frags[:-1]:
        assert s.receive_text(dumps(f), now=1) == []
    assert s.receive_text(dumps(frags[-1]), now=2) == [ops.Publish('/chatter', pub['msg'], 'p1')]
    assert len(s.reassembler) == 0


def test_fragments_may_arrive_as_cbor_frames():
    s = Session()
    frags = fragment_ops(dumps(SUB), 10, 'f')
    results = [r for f in frags for r in s.receive_bytes(cbor2.dumps(f), now=0)]
    assert results == [ops.Subscribe('/chatter', 'subscribe:/chatter:1', 'std_msgs/String')]


def test_fragment_errors_are_reported_with_the_fragment_id():
    s = Session()
    assert s.receive_text(dumps({'op': 'fragment', 'id': 'f', 'data': '{"op":', 'num': 0, 'total': 2}), 0) == []
    err = only_error(s.receive_text(dumps({'op': 'fragment', 'id': 'f', 'data': '1}', 'num': 1, 'total': 2}), 0))
    assert (err.op, err.id, err.message) == ('fragment', 'f', "field 'op' must be a string, got number")
    s.receive_text(dumps({'op': 'fragment', 'id': 'g', 'data': '{"op":', 'num': 0, 'total': 2}), 0)
    err = only_error(s.receive_text(dumps({'op': 'fragment', 'id': 'g', 'data': '}', 'num': 1, 'total': 2}), 0))
    assert (err.op, err.id) == ('fragment', 'g') and 'reassembled message: invalid JSON' in err.message
    # an op inside fragments that fails validation names the inner op and id
    frags = fragment_ops(dumps({'op': 'subscribe', 'id': 'inner'}), 8, 'outer')
    results = [r for f in frags for r in s.receive_text(dumps(f), now=0)]
    err = only_error(results)
    assert (err.op, err.id, err.message) == ('subscribe', 'inner', "subscribe: missing required field 'topic'")


def test_fragment_inside_fragment_is_refused():
    s = Session()
    inner = {'op': 'fragment', 'id': 'x', 'data': '{}', 'num': 0, 'total': 1}
    results = [r for f in fragment_ops(dumps(inner), 10, 'outer') for r in s.receive_text(dumps(f), now=0)]
    assert 'may not carry another fragment' in only_error(results).message


def test_incomplete_fragments_expire_with_an_error():
    s = Session(fragment_timeout=600)
    frags = fragment_ops(dumps(SUB), 10, 'slow')
    assert s.receive_text(dumps(frags[0]), now=0) == []
    assert s.expire(now=599) == []
    results = s.receive_text(dumps({'op': 'set_level', 'level': 'error'}), now=601)
    assert isinstance(results[0], ProtocolError) and results[1] == ops.SetLevel('error')
    assert (results[0].op, results[0].id) == ('fragment', 'slow')
    assert 'dropped after 600 s' in results[0].message
    assert len(s.reassembler) == 0
    # the rest of the expired message now cannot complete it
    assert all(not isinstance(r, ops.Subscribe)
               for f in frags[1:] for r in s.receive_text(dumps(f), now=602))


def test_fragment_flood_is_limited():
    s = Session(max_fragment_messages=4)
    errors = []
    for i in range(10):
        errors += s.receive_text(dumps({'op': 'fragment', 'id': f'f{i}', 'data': 'x', 'num': 0, 'total': 2}), 0)
    assert len(errors) == 6 and all('too many incomplete messages' in e.message for e in errors)
    assert all(e.close == 1008 for e in errors)
    s = Session(max_message_size=4000)
    errors = []
    for i in range(20):
        frame = dumps({'op': 'fragment', 'id': 'big', 'data': 'x' * 300, 'num': i, 'total': 20})
        errors += s.receive_text(frame, 0)
        if errors:
            break
    assert i < 19 and len(errors) == 1 and 'exceed 4000 bytes' in errors[0].message and errors[0].close == 1008
    assert s.receive_text(dumps(SUB), 0)[0].topic == '/chatter'


def test_fragments_refused_until_allowed():
    """Before authentication a fragment is refused, with 1008, before anything is stored."""
    s = Session()
    s.fragments_allowed = False
    frames = [dumps(f) for f in fragment_ops(dumps(SUB), 10, 'early')]
    [error] = s.receive_text(frames[0], 0)
    assert (error.op, error.id, error.close) == ('fragment', 'early', 1008)
    assert 'before authentication' in error.message
    assert len(s.reassembler) == 0 and s.reassembler.pending_bytes == 0
    s.fragments_allowed = True
    results = [r for f in frames for r in s.receive_text(f, 1)]
    assert [type(r) for r in results] == [ops.Subscribe]


def test_oversize_frames_are_refused():
    s = Session(max_message_size=100)
    big = dumps({'op': 'publish', 'topic': '/t', 'msg': {'data': 'x' * 200}})
    err = only_error(s.receive_text(big.decode(), now=0))
    assert err.message == f'message of {len(big)} bytes exceeds max_message_size 100'
    only_error(s.receive_bytes(cbor2.dumps({'op': 'publish', 'topic': '/t', 'msg': {'data': 'x' * 200}}), 0))
    # characters are counted as UTF-8 bytes
    wide = '{"op":"unsubscribe","topic":"/' + 'é' * 40 + '"}'
    assert len(wide) <= 100 < len(wide.encode())
    assert 'exceeds max_message_size' in only_error(s.receive_text(wide, 0)).message
    exact = '{"op":"unsubscribe","topic":"/' + 'x' * (100 - 32) + '"}'
    assert len(exact) == 100 and s.receive_text(exact, 0) == [ops.Unsubscribe('/' + 'x' * 68)]


def test_set_level_filters_status():
    s = Session()
    assert s.level == 'error'
    assert s.status('info', 'subscribed') is None
    assert s.status('warning', 'slow') is None
    assert s.status('error', 'bad', id='x') == {'op': 'status', 'level': 'error', 'msg': 'bad', 'id': 'x'}
    assert s.receive_text('{"op":"set_level","level":"info","id":"lv"}', 0) == [ops.SetLevel('info', 'lv')]
    assert s.level == 'info'
    assert s.status('info', 'subscribed') == {'op': 'status', 'level': 'info', 'msg': 'subscribed'}
    assert s.status('warn', 'w')['level'] == 'warning'
    s.receive_text('{"op":"set_level","level":"warning"}', 0)
    assert s.status('info', 'x') is None and s.status('warning', 'x') is not None
    s.receive_text('{"op":"set_level","level":"none"}', 0)
    assert s.status('error', 'x') is None
    err = only_error(s.receive_text('{"op":"set_level","level":"loud"}', 0))
    assert s.level == 'none' and err.op == 'set_level'


def test_status_names_the_op_once():
    s = Session()
    assert s.status('error', 'no such topic', op='publish', id='p')['msg'] == 'publish: no such topic'
    assert s.status('error', 'publish: no such topic', op='publish')['msg'] == 'publish: no such topic'
    err = ProtocolError('subscribe: missing required field \'topic\'', op='subscribe', id='s')
    assert s.error_status(err) == {'op': 'status', 'level': 'error', 'id': 's',
                                   'msg': "subscribe: missing required field 'topic'"}


def test_png_compressed_ops_are_accepted():
    s = Session()
    [png] = png_ops(dumps(SUB))
    assert s.receive_text(dumps(png), 0) == [ops.Subscribe('/chatter', 'subscribe:/chatter:1', 'std_msgs/String')]
    err = only_error(s.receive_text(dumps({'op': 'png', 'data': 'AAAA'}), 0))
    assert err.op == 'png'
    parts = png_ops(dumps(SUB), max_size=20, id='p')
    assert 'not supported' in only_error(s.receive_text(dumps(parts[0]), 0)).message
