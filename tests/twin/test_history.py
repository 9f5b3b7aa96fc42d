"""The gateway's history (/api/history): kept with no page open, equal to what a subscriber saw,
downsampled with min and max, refused with a reason, and still there after a restart."""

from __future__ import annotations

import time
import urllib.request
from contextlib import contextmanager

import pytest
import roslibpy

from tests.support.http import api
from tests.support.ros import client as connect, stream, twist
from tests.support.wait import wait_for

BATTERY = '/s01/battery_state'


@pytest.fixture(scope='module')
def fleet(start_gateway):
    return start_gateway('--fleet', '2', '--robot', 'rover')


def history(gw, topic, field, **params) -> tuple[int, dict]:
    query = '&'.join(f'{k}={v}' for k, v in {'topic': topic, 'field': field, **params}.items())
    return api(gw, 'GET', f'/api/history?{query}')


@contextmanager
def driving(ros, cmd_topic: str, move: dict, seconds: float, watched: str, type_: str, field: str):
    """Drives with ``move`` on cmd_topic for ``seconds`` (10 Hz) while noting ``field`` of every message
    of ``watched``; (start, end, the values noted) in wall time, still noting until the block ends."""
    seen: list[float] = []
    topic = roslibpy.Topic(ros, watched, type_)
    topic.subscribe(lambda m: seen.append(m[field]))
    cmd = roslibpy.Topic(ros, cmd_topic, 'geometry_msgs/msg/Twist')
    cmd.advertise()
    t0 = time.time()
    stream(cmd, move, seconds, rate=10)
    try:
        yield t0, time.time(), seen
    finally:
        topic.unsubscribe()
        cmd.unadvertise()


@pytest.fixture(scope='module')
def drove(fleet):
    """/s01 driven in a circle for 20 s while a subscriber notes every battery percentage it gets."""
    with connect(fleet) as ros, \
            driving(ros, '/s01/cmd_vel', twist(0.3, 0.5), 20, BATTERY, 'sensor_msgs/msg/BatteryState', 'percentage') \
            as (t0, t1, seen):
        wait_for(lambda: len(history(fleet, BATTERY, 'percentage', **{'from': t0, 'to': t1 + 5})[1]['t']) >= 15, 15, 0.2)
    return t0, t1, seen


def test_a_station_nobody_looks_at_is_kept_from_the_start(fleet):
    # no client has ever subscribed to /s02: the gateway's own subscription keeps it
    body = wait_for(lambda: (lambda b: b if len(b.get('t', [])) >= 2 else None)(
        history(fleet, '/s02/battery_state', 'percentage', **{'from': 0})[1]), 15, 0.2)
    assert body['topic'] == '/s02/battery_state' and body['field'] == 'percentage'
    assert all(0 < v <= 1 for v in body['v'])
    status, listing = api(fleet, 'GET', '/api/history')
    assert status == 200
    topics = {s['topic']: s['fields'] for s in listing['series']}
    assert 'percentage' in topics['/s02/battery_state'] and 'temperature' in topics['/s02/motor/left/temperature']
    assert 'twist.twist.linear.x' in topics['/s02/odom']


def test_twenty_seconds_of_driving_give_the_points_a_subscriber_saw(fleet, drove):
    t0, t1, seen = drove
    status, body = history(fleet, BATTERY, 'percentage', **{'from': t0, 'to': t1})
    assert status == 200, body
    assert len(body['t']) >= 15 and len(body['t']) == len(body['v'])
    assert all(t0 <= t <= t1 for t in body['t']) and body['t'] == sorted(body['t'])
    for v in body['v']:                                  # each kept value is one the subscriber received
        assert min(abs(v - s) for s in seen) < 1e-9, (v, seen[-5:])
    assert body['v'][0] > body['v'][-1]                  # the battery drained while driving
    _, speed = history(fleet, '/s01/odom', 'twist.twist.linear.x', **{'from': t0 + 3, 'to': t1})
    assert len(speed['v']) >= 10 and max(speed['v']) > 0.25


def test_step_downsamples_with_min_and_max(fleet, drove):
    t0, t1, _ = drove
    _, raw = history(fleet, BATTERY, 'percentage', **{'from': t0, 'to': t1})
    assert 'min' not in raw
    status, body = history(fleet, BATTERY, 'percentage', **{'from': t0, 'to': t1, 'step': 5})
    assert status == 200 and body['step'] == 5
    assert 3 <= len(body['t']) <= 6 and len(body['min']) == len(body['max']) == len(body['v'])
    for lo, v, hi in zip(body['min'], body['v'], body['max']):
        assert lo <= v <= hi
    assert any(lo < hi for lo, hi in zip(body['min'], body['max']))   # a bucket holds several points
    # (SQLite writes a raw read's JSON with 15 significant digits)
    assert min(body['min']) == pytest.approx(min(raw['v']), rel=1e-13)
    assert max(body['max']) == pytest.approx(max(raw['v']), rel=1e-13)
    with urllib.request.urlopen(f"{fleet.http_url}api/history?topic={BATTERY}&field=percentage"
                                f"&from={t0}&to={t1}&step=5&format=csv", timeout=10) as res:
        assert res.headers['Content-Type'].startswith('text/csv')
        lines = res.read().decode().splitlines()
    assert lines[0] == 't,v,min,max' and len(lines) == len(body['t']) + 1
    assert float(lines[1].split(',')[1]) == pytest.approx(body['v'][0])


def test_an_empty_span_gives_empty_arrays_and_mistakes_get_a_reason(fleet):
    status, body = history(fleet, BATTERY, 'percentage', **{'from': 1000, 'to': 2000})
    assert status == 200 and body['t'] == [] and body['v'] == []
    status, body = history(fleet, BATTERY, 'percentage', **{'from': 1000, 'to': 2000, 'step': 60})
    assert status == 200 and body['t'] == [] and body['min'] == []
    status, body = history(fleet, '/s01/scan', 'range_min')
    assert status == 404 and '/s01/scan is not in the history' in body['error']
    status, body = history(fleet, BATTERY, 'colour')
    assert status == 404 and "no field 'colour'" in body['error'] and 'percentage' in body['error']
    status, body = history(fleet, BATTERY, 'percentage', **{'from': 'yesterday'})
    assert status == 400 and '"from" is a number' in body['error']
    status, body = history(fleet, BATTERY, 'percentage', **{'from': 2000, 'to': 1000})
    assert status == 400 and 'after' in body['error']
    status, body = history(fleet, BATTERY, 'percentage', step=0)
    assert status == 400 and '"step"' in body['error']
    status, body = api(fleet, 'GET', f'/api/history?topic={BATTERY}')
    assert status == 400 and 'field' in body['error']
    assert fleet.alive


def test_size_and_rows_per_second_are_reported(fleet):
    body = wait_for(lambda: (lambda b: b if b['rows_per_second'] > 0 else None)(
        api(fleet, 'GET', '/api/history/stats')[1]), 15, 0.2)
    assert body['bytes'] > 0 and body['used_bytes'] > 0 and body['rows_written'] > 0
    assert body['db'].startswith('sqlite:///') and body['db'].endswith('rosgate.db')
    assert '/s01/battery_state' in body['topics']
    # 2 stations x 12 fields, about once a second
    assert 10 < body['rows_per_second'] < 60, body


def test_the_points_survive_a_restart(start_gateway, fleet, drove):
    t0, t1, _ = drove
    _, before = history(fleet, BATTERY, 'percentage', **{'from': t0, 'to': t1})
    fleet.stop()
    again = start_gateway('--fleet', '2', '--robot', 'rover', env={'XDG_DATA_HOME': fleet.data_home})
    status, after = history(again, BATTERY, 'percentage', **{'from': t0, 'to': t1})
    assert status == 200 and len(after['t']) >= 15
    n = len(before['t'])   # the last batch before the stop may have come after the first read
    assert after['t'][:n] == before['t'] and after['v'][:n] == before['v']


VIEWER = 'viewer-token-0a1b2c'


def test_reading_history_obeys_the_subscribe_rules(start_gateway, tmp_path):
    tokens = tmp_path / 'tokens.toml'
    tokens.write_text(f'[[tokens]]\nname = "vera"\nrole = "viewer"\ntoken = "{VIEWER}"\n')
    gw = start_gateway('--fleet', '1', '--robot', 'rover', '--auth', str(tokens),
                       '--topics-glob', "['/s01/battery_state', '/s01/cmd_vel', '/rosapi/*', '/s01/odom']")
    status, body = history(gw, BATTERY, 'percentage')
    assert status == 401 and 'token' in body['error']
    viewer = VIEWER
    wait_for(lambda: api(gw, 'GET', f'/api/history?topic={BATTERY}&field=percentage&from=0',
                         token=viewer)[1].get('t'), 15, 0.2)
    # a topic the name globs hide is neither kept nor readable
    status, body = api(gw, 'GET', '/api/history?topic=/s01/motor/left/temperature&field=temperature', token=viewer)
    assert status == 403 and 'not allowed for subscribe' in body['error']
    status, listing = api(gw, 'GET', '/api/history', token=viewer)
    assert {s['topic'] for s in listing['series']} == {BATTERY, '/s01/odom'}


def test_a_turtle_fleet_keeps_each_turtles_pose(start_gateway):
    gw = start_gateway('--fleet', '2')
    with connect(gw) as ros, \
            driving(ros, '/s01/turtle1/cmd_vel', twist(1.0, 0.3), 6, '/s01/turtle1/pose', 'turtlesim/msg/Pose', 'x') \
            as (t0, t1, seen):
        body = wait_for(lambda: (lambda b: b if len(b.get('t', [])) >= 4 else None)(
            history(gw, '/s01/turtle1/pose', 'x', **{'from': t0, 'to': t1})[1]), 15, 0.2)
    assert body['v'][-1] > body['v'][0]                 # it drove on
    for v in body['v']:
        assert min(abs(v - s) for s in seen) < 1e-6
    fields = {s['topic']: s['fields'] for s in api(gw, 'GET', '/api/history')[1]['series']}
    assert fields['/s02/turtle1/pose'] == ['x', 'y', 'theta', 'linear_velocity', 'angular_velocity']
