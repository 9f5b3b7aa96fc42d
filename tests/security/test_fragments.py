"""Fragments are bounded before anything else: on an --auth gateway none is taken before the
client authenticates, and an authenticated client's pending pieces share the frame limit. A
client past a bound gets a status and close code 1008. Measured on a real gateway process."""

from __future__ import annotations

import json

import pytest
from websockets.exceptions import ConnectionClosed

from tests.support.auth import TOKENS
from tests.support.process import proc_bytes
from tests.support.wsclient import Client

FLOOD = 200_000
MB = 2**20


@pytest.fixture(scope='module')
def guarded(launch, tokens_file):
    return launch('--auth', tokens_file, '--max-message-size', '1000000')


def flood(c: Client, fid: str, total: int) -> int:
    """Empty pieces of one message until the server ends the connection; how many were sent."""
    for num in range(FLOOD):
        try:
            c.send(json.dumps({'op': 'fragment', 'id': fid, 'data': '', 'num': num, 'total': total}))
        except ConnectionClosed:
            return num
    return FLOOD


def rss_after_a_round_trip(gw, c: Client) -> int:
    """The gateway's resident memory once it has read everything c sent (or c was closed)."""
    try:
        c.send({'op': 'call_service', 'id': 'barrier', 'service': '/rosapi/get_time'})
        c.expect(lambda m: m.get('id') == 'barrier', timeout=60)
    except ConnectionClosed:
        pass
    return proc_bytes(gw.pid)


def test_empty_fragments_before_auth_end_the_connection(guarded):
    with Client(guarded.ws_url) as warm:   # the first connection's one-time costs are not the flood's
        warm.send({'op': 'call_service', 'id': 'w', 'service': '/rosapi/get_time'})
        warm.status('w')
    before = proc_bytes(guarded.pid)
    with Client(guarded.ws_url) as c:
        sent = flood(c, 'flood', 2**31 - 1)
        after = rss_after_a_round_trip(guarded, c)
        code = c.closed_code(timeout=30)
    grown = after - before
    print(f'{sent} fragments sent before the close; RSS grew {grown / MB:.2f} MB')
    assert code == 1008
    assert grown < 4 * MB, f'the gateway grew {grown / MB:.1f} MB'
    refusal = next(m for m in c.seen if m.get('op') == 'status')
    assert refusal['id'] == 'flood' and 'not accepted before authentication' in refusal['msg']
    assert guarded.alive


def test_one_fragment_before_auth_gets_a_status_and_1008(guarded):
    with Client(guarded.ws_url) as c:
        c.send({'op': 'fragment', 'id': 'early', 'data': '{"op":', 'num': 0, 'total': 2})
        assert 'not accepted before authentication' in c.status('early')['msg']
        assert c.closed_code(timeout=10) == 1008
    with Client(guarded.ws_url, TOKENS['viewer']) as other:   # others are served meanwhile
        assert other.call('/rosapi/get_time')['result']


def call_in_fragments(c: Client, id: str, size: int = 20) -> dict:
    call = json.dumps({'op': 'call_service', 'id': id, 'service': '/add_two_ints', 'args': {'a': 20, 'b': 22}})
    parts = [call[i:i + size] for i in range(0, len(call), size)]
    for num, part in enumerate(parts):
        c.send({'op': 'fragment', 'id': id, 'data': part, 'num': num, 'total': len(parts)})
    return c.expect(lambda m: m.get('id') == id and m.get('op') == 'service_response')


def test_fragmented_message_after_auth_works(guarded):
    with Client(guarded.ws_url) as c:     # auth as an op, then a fragmented call
        c.send({'op': 'auth', 'token': TOKENS['operator']})
        assert c.call('/rosapi/get_time')['result']
        assert call_in_fragments(c, 'after-auth')['values'] == {'sum': 42}
    with Client(guarded.ws_url, TOKENS['operator']) as c:   # the token at connect signs in as well
        assert call_in_fragments(c, 'token-at-connect')['values'] == {'sum': 42}


def test_authenticated_flood_of_empty_pieces_is_bounded(guarded):
    with Client(guarded.ws_url, TOKENS['viewer']) as c:
        sent = flood(c, 'flood', 1000000)
        assert sent < FLOOD
        code = c.closed_code(timeout=30)
        assert code == 1008
        refusal = next(m for m in c.seen if m.get('op') == 'status')
        assert refusal['id'] == 'flood' and 'exceed 1000000 bytes' in refusal['msg']


def test_total_past_the_frame_limit_is_refused(guarded):
    with Client(guarded.ws_url, TOKENS['viewer']) as c:
        c.send({'op': 'fragment', 'id': 'vast', 'data': 'x', 'num': 0, 'total': 2**31 - 1})
        assert 'total 2147483647 exceeds the message limit of 1000000 bytes' in c.status('vast')['msg']
        assert c.closed_code(timeout=10) == 1008
