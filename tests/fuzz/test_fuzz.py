"""Property-based fuzzing of a live gateway: mutated and random ops, JSON and CBOR, text and
binary frames. Whatever arrives: the process lives, no connection is dropped (only 1008/1009
closes are allowed), every op with a definite defect and an id gets an error status with that
id, a control client's round trips keep working, and RSS stays bounded."""

from __future__ import annotations

import json
import time

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from tests.fuzz.client import Closed, FuzzConn, rss_bytes
from tests.fuzz.frames import frame
from tests.gateway.rawclient import Raw

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
        self.rss_start = rss_bytes(gw.pid)
        self.frames = self.bad = self.reconnects = 0
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


def _reconnect(state: State, closed: Closed) -> None:
    assert closed.code in (1008, 1009), f'connection dropped with {closed.code} {closed.reason!r}'
    state.reconnects += 1
    state.conn = FuzzConn(state.gw.ws_url)


@settings(max_examples=EXAMPLES, deadline=None, database=None, phases=[Phase.generate],
          suppress_health_check=list(HealthCheck))
@given(rng=st.randoms(use_true_random=False), count=st.integers(1, 10))
def test_fuzzed_frames(state, rng, count):
    frames = [frame(rng) for _ in range(count)]   # drawn even past the budget: hypothesis wants
    if time.monotonic() > state.deadline:           # every example to draw the same way
        return
    conn = state.conn
    try:
        for f in frames:
            if f.bad_id:
                conn.send(SET_LEVEL)   # a fuzzed set_level before it may have silenced errors
            conn.send(f.payload)
        got = conn.barrier()
    except Closed as closed:
        _reconnect(state, closed)
        return
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
    assert state.gw.alive
    assert state.control.call('/add_two_ints', {'a': 2, 'b': 3})['values'] == {'sum': 5}
    growth = rss_bytes(state.gw.pid) - state.rss_start
    assert growth < RSS_GROWTH, f'RSS grew by {growth / 2**20:.1f} MiB'
