"""Attempts end to end on the sim: a gateway with tokens and an exercises folder, students driving
turtle1 through roslibpy; the goal is checked on /turtle1/pose by the gateway, the result is read
back through the API (and so from the store)."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import pytest
import roslibpy

from tests.support.auth import TOKENS, tokens_toml
from tests.support.http import api, http
from tests.support.ros import client
from tests.support.wait import wait_for

EAST = {'title': 'East of the start', 'station_kind': 'turtlesim', 'time_limit': 30,
        'start': {'text': 'drive east'}, 'pose_topic': 'pose',
        'goal': {'all': [{'region': {'xmin': 7, 'xmax': 11, 'ymin': 0, 'ymax': 11}}, {'within': 25},
                         {'clearance': 0.2}]}}
NOWHERE = {'title': 'A corner nobody reaches', 'time_limit': 1.5,
           'goal': {'region': {'xmin': 0, 'xmax': 0.5, 'ymin': 0, 'ymax': 0.5}}}
ALICE, BOB, TEACHER = TOKENS['operator'], TOKENS['operator2'], TOKENS['admin']


@pytest.fixture(scope='module')
def gw(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('exercises')
    tokens = folder.parent / 'tokens.toml'
    tokens.write_text(tokens_toml())
    (folder / 'east.json').write_text(json.dumps(EAST))
    return start_gateway('--auth', str(tokens), '--exercises-dir', str(folder))


def attempt_result(gw, attempt: str, token: str) -> dict:
    status, body = api(gw, 'GET', f'/api/attempts/{attempt}', token=token)
    assert status == 200, body
    return body


def test_the_goal_reached_is_passed_with_score_1(gw):
    status, body = api(gw, 'GET', '/api/exercises/east', token=ALICE)
    assert status == 200 and body['goal'] == EAST['goal'] and body['start'] == {'text': 'drive east'}
    with client(gw, ALICE) as ros:
        cmd = roslibpy.Topic(ros, '/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
        pose = roslibpy.Topic(ros, '/turtle1/pose', 'turtlesim/msg/Pose')
        poses: list = []
        pose.subscribe(poses.append)
        wait_for(lambda: poses, what='a pose of turtle1')
        assert poses[-1]['x'] < 7                          # not there yet: the attempt has work to do
        status, started = api(gw, 'POST', '/api/exercises/east/attempts',
                              {'station': '/turtle1', 'program': 'forward 2 m/s'}, token=ALICE)
        assert status == 201, started
        assert attempt_result(gw, started['attempt'], ALICE)['live'] is True

        def driven():
            cmd.publish(roslibpy.Message({'linear': {'x': 2.0, 'y': 0.0, 'z': 0.0},
                                          'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}))
            return not attempt_result(gw, started['attempt'], ALICE)['live']
        wait_for(driven, timeout=20, what='the goal reached')
        cmd.publish(roslibpy.Message({'linear': {'x': 0.0, 'y': 0.0, 'z': 0.0},
                                      'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}))
        pose.unsubscribe()
    result = attempt_result(gw, started['attempt'], ALICE)
    assert result['passed'] is True and result['score'] == 1.0 and result['why'] == 'goal'
    assert result['program'] == 'forward 2 m/s' and result['exercise'] == 'east' and result['name'] == 'alice'
    assert result['ended_at'] >= result['started_at']
    replay_of_the_attempt(gw, result['recording'])


def replay_of_the_attempt(gw, recording: str) -> None:
    """The attempt's recording: the teacher reads it (and another student may not); it holds the
    robot's poses, which went east, and the commands that drove it."""
    from rosbags.highlevel import AnyReader
    assert recording, 'the attempt was not recorded'
    assert http(gw, f'/api/recordings/{recording}.mcap', token=BOB).status == 403
    mcap = http(gw, f'/api/recordings/{recording}.mcap', token=TEACHER)
    assert mcap.status == 200, mcap
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / 'attempt.mcap'
        path.write_bytes(mcap.body)
        with AnyReader([path]) as reader:
            topics = {c.topic for c in reader.connections}
            poses = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()
                     if c.topic == '/turtle1/pose']
    assert {'/turtle1/pose', '/turtle1/cmd_vel'} <= topics, topics
    assert len(poses) > 5 and poses[-1].x > poses[0].x + 0.5, [p.x for p in poses[:3]]


def test_a_missed_goal_is_recorded_as_failed(gw):
    status, made = api(gw, 'POST', '/api/exercises', {'id': 'nowhere', **NOWHERE}, token=TEACHER)
    assert status == 201, made
    assert api(gw, 'POST', '/api/exercises', {'id': 'x', **NOWHERE}, token=BOB)[0] == 403
    assert api(gw, 'POST', '/api/exercises', {'id': 'bad', 'goal': {'exec': 'rm'}}, token=TEACHER)[0] == 400
    status, started = api(gw, 'POST', '/api/exercises/nowhere/attempts',
                          {'station': '/turtle1', 'program': 'wait'}, token=BOB)
    assert status == 201, started
    result = wait_for(lambda: (r := attempt_result(gw, started['attempt'], BOB)) and not r['live'] and r,
                      what='the time limit')
    assert result['passed'] is False and result['score'] == 0.0 and result['why'] == 'time'
    assert result['ended_at'] - result['started_at'] >= 1.5


def test_results_are_private(gw):
    wait_for(lambda: api(gw, 'GET', '/api/exercise-results', token=TEACHER)[1]['results'], what='results')
    _, mine = api(gw, 'GET', '/api/exercise-results', token=BOB)
    assert mine['results'] and {r['name'] for r in mine['results']} == {'bob'}
    alice = next(r for r in api(gw, 'GET', '/api/exercise-results', token=ALICE)[1]['results'])
    assert api(gw, 'GET', f"/api/exercise-results?person={alice['person']}", token=BOB)[0] == 403
    assert api(gw, 'GET', f"/api/attempts/{alice['attempt']}", token=BOB)[0] == 403
    status, everyone = api(gw, 'GET', '/api/exercise-results', token=TEACHER)
    assert status == 200
    summary = {(s['name'], s['exercise']): s for s in everyone['summary']}
    assert summary[('alice', 'east')]['best']['passed'] is True
    assert summary[('bob', 'nowhere')]['last']['passed'] is False
    assert api(gw, 'GET', '/api/exercise-results')[0] == 401


def test_an_attempt_on_a_topic_the_station_lacks_is_refused(gw):
    status, body = api(gw, 'POST', '/api/exercises/east/attempts', {'station': '/no_robot'}, token=ALICE)
    assert status == 409 and '/no_robot/pose' in body['error']
