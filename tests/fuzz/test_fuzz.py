"""Property-based fuzzing of a live gateway: mutated and random ops, JSON and CBOR, text and
binary frames. Whatever arrives: the process lives, no connection is dropped, every op with a
definite defect and an id gets an error status with that id, a control client's round trips keep
working, and RSS stays bounded.

The only closes allowed are the gateway's own, each one explained to the client: 1007 for a text
frame that is not UTF-8 (an error status naming it, then the close with a reason; the fuzzer
sends a few and each must get exactly that), 1008 (a reason: the client does not read its
replies; or, past the op rate limit, after the refusal statuses) and 1009 (tornado's hard
frame limit: no status can come first, so the reason must say it)."""

from __future__ import annotations

import json
import time

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from tests.support.fuzzclient import Closed, FuzzConn
from tests.support.fuzzframes import frame
from tests.support.process import proc_bytes
from tests.support.rawclient import Raw

EXAMPLES = 1000
BUDGET = 20.0   # seconds of fuzzing at most; examples past it are skipped (a slow machine runs fewer)
MIN_FRAMES = 200
RSS_GROWTH = 50 * 2**20
SET_LEVEL = json.dumps({'op': 'set_level', 'level': 'error'})


class State:
    def __init__(self, gw):
        self.gw = gw
        self.conn = FuzzConn(gw.ws_url)
        self.control = Raw(gw.ws_url)
        self.control.sync()
        self.conn.barrier()
        self.rss_start = proc_bytes(gw.pid)
        self.frames = self.bad = self.reconnects = 0
        self.closes: dict[int, int] = {}   # close code -> count
        self.deadline = time.monotonic() + BUDGET


@pytest.fixture(scope='module')
def state(start_gateway):
    # no robots: the suite is about the gateway (tests/fuzz/hammer.py runs with turtlesim)
    gw = start_gateway('--fibonacci-interval', '0.01', '--max-message-size', '262144', '--robot', 'none')
    s = State(gw)
    yield s
    s.control.close()
    if not s.conn.closed:
        s.conn.close()


def _reconnect(state: State, closed: Closed, expected: int | None) -> None:
    """A close is allowed only as the gateway's rule has it: see the module docstring."""
    code, reason, status = closed.code, closed.reason, closed.last_status
    assert code == expected or (expected is None and code in (1008, 1009)), \
        f'connection closed with {code} {reason!r} (expected {expected}); last status {status}'
    assert reason, f'a {code} close without a reason; last status {status}'
    if code == 1007:
        assert status and status['level'] == 'error' and 'not valid UTF-8' in status['msg'], \
            f'a 1007 close ({reason!r}) without an error status naming the UTF-8 first: {status}'
    elif code == 1008 and 'rate limit' in reason:
        assert status, f'a 1008 close ({reason!r}) with no refusal status before it'
    state.reconnects += 1
    state.closes[code] = state.closes.get(code, 0) + 1
    state.conn = FuzzConn(state.gw.ws_url)


@settings(max_examples=EXAMPLES, deadline=None, database=None, phases=[Phase.generate],
          suppress_health_check=list(HealthCheck))
@given(rng=st.randoms(use_true_random=False), count=st.integers(1, 10))
def test_fuzzed_frames(state, rng, count):
    frames = [frame(rng) for _ in range(count)]   # drawn even past the budget: hypothesis wants
    if time.monotonic() > state.deadline:           # every example to draw the same way
        return
    conn = state.conn
    closing = next((f.close for f in frames if f.close), None)
    try:
        for f in frames:
            if f.bad_id or f.close:
                conn.send(SET_LEVEL)   # a fuzzed set_level before it may have silenced errors
            conn.send(f.payload, f.text)
        got = conn.barrier()
    except Closed as closed:
        _reconnect(state, closed, closing)
        return
    assert closing is None, f'no {closing} close after {[f.payload for f in frames if f.close]!r}'
    answered = {m.get('id') for m in got if m.get('op') == 'status' and m.get('level') == 'error'}
    unanswered = [f for f in frames if f.bad_id and f.bad_id not in answered]
    assert not unanswered, f'no error status for {[f.payload for f in unanswered]!r}'
    bugs = [m['msg'] for m in got if m.get('op') == 'status' and 'internal error' in m.get('msg', '')]
    assert not bugs, f'the gateway failed on {[f.payload for f in frames]!r}: {bugs}'
    assert state.control.call('/add_two_ints', {'a': count, 'b': 1})['values'] == {'sum': count + 1}
    assert state.gw.alive
    state.frames += count
    state.bad += sum(1 for f in frames if f.bad_id)


def test_after_fuzzing_the_gateway_lives_and_rss_is_bounded(state):
    assert state.frames > MIN_FRAMES and state.bad > 0
    assert state.closes.get(1007), f'no frame that is not UTF-8 was sent (closes {state.closes})'
    assert state.gw.alive
    assert state.control.call('/add_two_ints', {'a': 2, 'b': 3})['values'] == {'sum': 5}
    growth = proc_bytes(state.gw.pid) - state.rss_start
    assert growth < RSS_GROWTH, f'RSS grew by {growth / 2**20:.1f} MiB'
