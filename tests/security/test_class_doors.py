"""What one student can do to a class (issue 46), tried from outside as the students did: operators
alice and bob, a viewer and the teacher, against --robot turtlesim --fleet 2 --exclusive-control --auth
--allow-runs --exercises-dir --blocks-dir --mesh-path. What a person may not subscribe to, publish or
call over the websocket they may not reach through a recording either; a station's services and
topics are its holder's; an attempt is driven, not teleported; program reports carry the gateway's
stamp; caps per person; no secret or server path in an answer; bad input is a 400 naming its field."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import pytest

from tests.support.auth import TOKENS, tokens_toml
from tests.support.http import api, http
from tests.support.wait import wait_for
from tests.support.wsclient import TWIST, Client, twist

ALICE, BOB, TEACHER, VIEWER = TOKENS['operator'], TOKENS['operator2'], TOKENS['admin'], TOKENS['viewer']
POSE = 'turtlesim/msg/Pose'
STRING = 'std_msgs/msg/String'
S01_CMD, S01_POSE = '/s01/turtle1/cmd_vel', '/s01/turtle1/pose'
EAST = {'title': 'East', 'station_kind': 'turtlesim', 'time_limit': 60, 'pose_topic': 'turtle1/pose',
        'goal': {'region': {'xmin': 8, 'xmax': 11, 'ymin': 0, 'ymax': 11}}}
PEN = {**EAST, 'title': 'East with a teleport allowed', 'allow_services': ['turtle1/teleport_absolute']}
SLOW = {**EAST, 'title': 'A corner', 'time_limit': 600, 'goal': {'region': {'xmin': 0, 'xmax': 0.3, 'ymin': 0, 'ymax': 0.3}}}
PASSWORD = 'hunter2-in-the-url'
STL = b'solid box\nendsolid box\n'
WAIT = 20.0   # s: a loaded 2-core machine's deadline for a gateway's answer


@pytest.fixture(scope='module')
def base(tmp_path_factory):
    base = tmp_path_factory.mktemp('class46')
    ex = base / 'exercises'
    ex.mkdir()
    for name, body in (('east', EAST), ('pen', PEN), ('slow', SLOW)):
        (ex / f'{name}.json').write_text(json.dumps(body))
    (base / 'blocks').mkdir()
    (base / 'gauges.json').write_text(json.dumps({'battery': {'min': 0, 'max': 100}}))
    # a colcon --symlink-install workspace: install/.../share/PKG/meshes/base.stl -> src/PKG/meshes/base.stl
    src = base / 'ws' / 'src' / 'robot_description' / 'meshes'
    src.mkdir(parents=True)
    (src / 'base.stl').write_bytes(STL)
    share = base / 'ws' / 'install' / 'robot_description' / 'share' / 'robot_description' / 'meshes'
    share.mkdir(parents=True)
    (share / 'base.stl').symlink_to(src / 'base.stl')
    (base / 'tokens.toml').write_text(tokens_toml())
    return base


@pytest.fixture(scope='module')
def school(launch, base):
    env = {'AMENT_PREFIX_PATH': str(base / 'ws' / 'install' / 'robot_description')}
    return launch('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--auth', str(base / 'tokens.toml'),
                  '--allow-runs', '--exercises-dir', str(base / 'exercises'), '--blocks-dir', str(base / 'blocks'),
                  '--mesh-path', str(base / 'ws' / 'src'), '--gauges', str(base / 'gauges.json'),
                  '--db', f'sqlite:///{base / "store.db"}?password={PASSWORD}', '--runs-dir', str(base / 'runs'),
                  '--recordings-dir', str(base / 'recordings'), '--cmd-timeout', '0', env=env)


def started_attempt(gw, token: str, exercise: str, station: str) -> str:
    status, body = api(gw, 'POST', f'/api/exercises/{exercise}/attempts', {'station': station, 'program': 'p'}, token)
    assert status == 201, body
    return body['attempt']


def stop_attempt(gw, attempt: str, token: str = TEACHER) -> dict:
    return api(gw, 'POST', f'/api/attempts/{attempt}/stop', token=token)[1]


def release(gw, who: Client) -> None:
    who.publish('/rosgate/control', {'data': 'release'})
    who.sync()


# --- 1. another student's run output through a recording -----------------------------------------

def test_a_recording_takes_only_what_its_starter_may_subscribe_to(school):
    """bob's recording of /rosgate/runs/* took alice's run output; now it takes what bob may subscribe
    to (none of alice's runs), while alice's own recording of the same globs has her output."""
    bobs = api(school, 'POST', '/api/recordings', {'topics': ['/rosgate/runs/*'], 'max_seconds': 120}, BOB)[1]
    alices = api(school, 'POST', '/api/recordings', {'topics': ['/rosgate/runs/*'], 'max_seconds': 120}, ALICE)[1]
    source = 'import time\nfor i in range(300):\n    print("secret answer 42", flush=True)\n    time.sleep(0.2)\n'
    status, run = api(school, 'POST', '/api/runs', {'source': source, 'ns': '/s02'}, ALICE)
    assert status == 201, run
    with Client(school.ws_url, BOB) as bob:     # the websocket refuses bob the same topic
        refused = bob.refusal({'op': 'subscribe', 'topic': f"/rosgate/runs/{run['id']}/output", 'type': STRING})
        assert refused and 'alice' in refused['msg'], refused
    wait_for(lambda: api(school, 'GET', f"/api/recordings/{alices['id']}", token=ALICE)[1]['messages'] >= 3, 60, 0.1,
             what='alice recording her run output')
    api(school, 'DELETE', f"/api/runs/{run['id']}", token=ALICE)
    for rec in (bobs, alices):
        assert api(school, 'DELETE', f"/api/recordings/{rec['id']}", token=ALICE if rec is alices else BOB)[0] == 200
    bobs_file = http(school, f"/api/recordings/{bobs['id']}.mcap", token=BOB)
    assert bobs_file.status == 200, bobs_file
    assert b'secret answer' not in bobs_file.body and run['id'].encode() not in bobs_file.body
    assert api(school, 'GET', f"/api/recordings/{bobs['id']}", token=BOB)[1]['topics'] == []
    alices_file = http(school, f"/api/recordings/{alices['id']}.mcap", token=ALICE)
    assert alices_file.status == 200 and b'secret answer 42' in alices_file.body


# --- 2. blocks from outside are data (the page's own check: tests/ide/test_shared_content.py) -------------

def made(**json_) -> dict:
    return {'json': {'type': 'my_hello', 'message0': 'say hello %1', 'previousStatement': None, 'nextStatement': None,
                     'args0': [{'type': 'input_value', 'name': 'F0', 'check': 'String'}], 'tooltip': 'publish /chatter',
                     **json_},
            'spec': {'kind': 'publish', 'topic': '/chatter', 'type': 'std_msgs/msg/String', 'msg': {'data': '$F0'}},
            'toolboxInputs': {'F0': {'shadow': {'type': 'text', 'fields': {'TEXT': 'hi'}}}}}


@pytest.mark.parametrize('field, bad', [
    ('helpUrl', 'javascript:fetch("/api/blocks/shared")'), ('helpUrl', ' JaVa\tScRiPt:alert(1)'),
    ('helpUrl', 'data:text/html,<script>alert(1)</script>'), ('tooltip', 'javascript:alert(1)'),
    ('message0', 'say <img src=x onerror=alert(1)> %1'), ('args0', [{'type': 'field_image', 'src': 'javascript:alert(1)'}]),
    ('extensions', ['ros_typed_name']), ('type', 'controls_if'), ('onchange', 'alert(1)')])
def test_the_class_library_takes_blocks_as_data_only(school, field, bad):
    status, body = api(school, 'POST', '/api/blocks/shared', made(**{field: bad}), TEACHER)
    assert status == 400 and field in body['error'], body
    assert all(m['json']['type'] != 'controls_if' for m in api(school, 'GET', '/api/blocks', token=ALICE)[1]['shared'])


def test_a_good_block_is_published_and_a_bad_set_or_kept_block_is_left_out(school, base):
    status, body = api(school, 'POST', '/api/blocks/shared', made(helpUrl='https://docs.ros.org/'), TEACHER)
    assert status == 200, body
    (base / 'blocks' / 'evil.json').write_text(json.dumps({'name': 'evil', 'blocks': [
        {'type': 'evil_help', 'message0': 'help me', 'helpUrl': 'javascript:alert(document.cookie)'}]}))
    (base / 'blocks' / 'fine.json').write_text(json.dumps({'name': 'fine', 'blocks': [
        {'type': 'fine_block', 'message0': 'fine', 'helpUrl': 'https://example.org/help'}]}))
    shared = base / 'blocks' / 'shared.json'
    kept = json.loads(shared.read_text())
    shared.write_text(json.dumps({'made': kept['made'] + [made(type='my_evil', helpUrl='javascript:alert(1)')]}))
    got = api(school, 'GET', '/api/blocks', token=ALICE)[1]
    assert [s['name'] for s in got['sets']] == ['fine'] and 'evil.json' in got['skipped'][0]['file']
    assert 'helpUrl' in got['skipped'][0]['why']
    assert [m['json']['type'] for m in got['shared']] == ['my_hello']


# --- 3. a station's services are its holder's; an attempt is driven, not teleported ---------------

def test_a_stations_services_and_topics_are_its_holders(school):
    with Client(school.ws_url, ALICE) as alice, Client(school.ws_url, BOB) as bob, \
            Client(school.ws_url, TEACHER) as teacher, Client(school.ws_url, VIEWER) as watcher:
        alice.publish(S01_CMD, twist(0.0), TWIST)
        alice.publish(S01_CMD, twist(0.1), TWIST)     # she drives /s01: its lease is hers
        alice.sync()
        watcher.subscribe(S01_POSE, POSE)
        try:
            for service, args in (('/s01/turtle1/teleport_absolute', {'x': 0.5, 'y': 0.5, 'theta': 0.0}),
                                  ('/s01/kill', {'name': 'turtle1'}), ('/s01/spawn', {'x': 1.0, 'y': 1.0, 'theta': 0.0}),
                                  ('/s01/reset', {})):
                refused = bob.call(service, args, timeout=WAIT)
                assert refused['result'] is False and 'alice' in refused['values'], (service, refused)
                status = bob.expect(lambda m: m.get('op') == 'status' and m.get('level') == 'error'
                                    and m.get('id') == refused['id'], WAIT)
                assert service in status['msg']
            # bob's pose on her pose topic reaches nobody: refused at the door with a status
            pose = {'x': 0.5, 'y': 0.5, 'theta': 0.0, 'linear_velocity': 0.0, 'angular_velocity': 0.0}
            refused = bob.refusal({'op': 'publish', 'topic': S01_POSE, 'type': POSE, 'msg': pose})
            assert refused and 'alice' in refused['msg'], refused
            watcher.sync()
            assert not any(m.get('topic') == S01_POSE and m['msg']['x'] == 0.5 for m in watcher.seen)
            # the holder and the teacher may
            assert alice.call('/s01/turtle1/teleport_relative', {'linear': 0.0, 'angular': 0.0}, timeout=WAIT)['result']
            assert teacher.call('/s01/turtle1/teleport_relative', {'linear': 0.0, 'angular': 0.0}, timeout=WAIT)['result']
            # watching stays open
            bob.subscribe(S01_POSE, POSE)
            assert bob.next_message(S01_POSE, timeout=WAIT)['x'] > 0
        finally:
            alice.publish(S01_CMD, twist(0.0), TWIST)
            release(school, alice)


def test_an_attempt_is_driven_not_teleported(school):
    """alice passed in a second by teleporting into the goal, bob failed her by teleporting her turtle
    into the wall: during an attempt the station's teleport, reset, spawn and kill are refused to
    everyone, and its commands and poses are hers."""
    attempt = started_attempt(school, ALICE, 'east', '/s01')
    try:
        with Client(school.ws_url, ALICE) as alice, Client(school.ws_url, BOB) as bob, \
                Client(school.ws_url, TEACHER) as teacher:
            for who in (alice, bob, teacher):
                refused = who.call('/s01/turtle1/teleport_absolute', {'x': 9.0, 'y': 5.0, 'theta': 0.0}, timeout=WAIT)
                assert refused['result'] is False and 'moves the robot' in refused['values'], refused
            refused = bob.call('/s01/reset', timeout=WAIT)
            assert refused['result'] is False, refused
            refused = bob.refusal({'op': 'publish', 'topic': S01_CMD, 'type': TWIST, 'msg': twist(2.0)})
            assert refused and "alice's live exercise attempt" in refused['msg'], refused
            body = api(school, 'GET', f'/api/attempts/{attempt}', token=ALICE)[1]
            assert body['live'] is True, body     # nothing moved the turtle into the goal
            # driving it there passes: the gateway checks the goal on the robot as it is driven
            def driven():
                alice.publish(S01_CMD, twist(2.0), TWIST)
                return not api(school, 'GET', f'/api/attempts/{attempt}', token=ALICE)[1]['live']
            wait_for(driven, 60, 0.1, what='the goal reached by driving')
            alice.publish(S01_CMD, twist(0.0), TWIST)
            release(school, alice)
        result = api(school, 'GET', f'/api/attempts/{attempt}', token=ALICE)[1]
        assert result['passed'] is True and result['why'] == 'goal', result
    finally:
        stop_attempt(school, attempt)
    with Client(school.ws_url, ALICE) as alice:    # the attempt over, her teleport home works again
        assert alice.call('/s01/turtle1/teleport_absolute', {'x': 5.5, 'y': 5.5, 'theta': 0.0}, timeout=WAIT)['result']
        release(school, alice)


def test_an_exercise_lists_the_services_it_allows(school):
    attempt = started_attempt(school, ALICE, 'pen', '/s01')
    try:
        with Client(school.ws_url, ALICE) as alice:
            assert alice.call('/s01/turtle1/teleport_absolute', {'x': 5.0, 'y': 5.0, 'theta': 0.0}, timeout=WAIT)['result']
            assert alice.call('/s01/turtle1/teleport_relative', {'linear': 0.0, 'angular': 0.0},
                              timeout=WAIT)['result'] is False
            release(school, alice)
    finally:
        stop_attempt(school, attempt)


def test_another_persons_attempt_is_not_ended_by_starting_one(school):
    attempt = started_attempt(school, ALICE, 'slow', '/s01')
    try:
        status, body = api(school, 'POST', '/api/exercises/slow/attempts', {'station': '/s01', 'program': 'p'}, BOB)
        assert status == 409 and 'alice' in body['error'], body
        assert api(school, 'GET', f'/api/attempts/{attempt}', token=ALICE)[1]['live'] is True
    finally:
        stop_attempt(school, attempt)


@pytest.fixture(scope='module')
def open_class(launch, base):
    """The same class without --exclusive-control."""
    return launch('--robot', 'turtlesim', '--fleet', '2', '--auth', str(base / 'tokens.toml'),
                  '--exercises-dir', str(base / 'exercises'), '--cmd-timeout', '0')


def test_without_the_lease_an_attempt_is_not_ended_by_another_nor_started_on_her_station(open_class):
    with Client(open_class.ws_url, ALICE) as alice:
        assert alice.call('/s01/fleet/claim', timeout=WAIT)['values']['success'] is True
        attempt = started_attempt(open_class, ALICE, 'slow', '/s01')
        status, body = api(open_class, 'POST', '/api/exercises/slow/attempts', {'station': '/s01', 'program': 'p'}, BOB)
        assert status == 409 and 'alice' in body['error'], body
        assert api(open_class, 'GET', f'/api/attempts/{attempt}', token=ALICE)[1]['live'] is True
        with Client(open_class.ws_url, BOB) as bob:
            refused = bob.call('/s01/turtle1/teleport_absolute', {'x': 0.5, 'y': 0.5, 'theta': 0.0}, timeout=WAIT)
            assert refused['result'] is False, refused
        stop_attempt(open_class, attempt)
        # her station, no attempt live: still not bob's to start one on
        status, body = api(open_class, 'POST', '/api/exercises/slow/attempts', {'station': '/s01', 'program': 'p'}, BOB)
        assert status == 409 and 'alice' in body['error'], body


# --- 4. program reports: stamped by the gateway, read by their writer and the teacher ---------------

def report(**kw) -> dict:
    return {'data': json.dumps({'user': 'alice', 'name': 'forged', 'state': 'running', 'error': '', 'program': None,
                                'line': None, 'at': 0, **kw})}


def test_program_reports_are_stamped_and_kept_to_their_station(school):
    with Client(school.ws_url, ALICE) as alice, Client(school.ws_url, BOB) as bob, \
            Client(school.ws_url, TEACHER) as teacher, Client(school.ws_url, VIEWER) as viewer:
        assert alice.call('/s01/fleet/claim', timeout=WAIT)['values']['success'] is True
        assert bob.call('/s02/fleet/claim', timeout=WAIT)['values']['success'] is True
        try:
            teacher.subscribe('/s02/rosgate/program', STRING)
            teacher.subscribe('/s01/rosgate/program', STRING)
            # bob's report on his own station says "alice": the gateway says bob, from his connection
            bob.publish('/s02/rosgate/program', report(), STRING)
            got = json.loads(teacher.next_message('/s02/rosgate/program', timeout=WAIT)['data'])
            assert got['user'] == 'bob' and got['by']['name'] == 'bob' and isinstance(got['by']['client'], int), got
            # on alice's station his report is refused
            refused = bob.refusal({'op': 'publish', 'topic': '/s01/rosgate/program', 'type': STRING, 'msg': report()})
            assert refused and 'alice' in refused['msg'], refused
            # her own is shown as hers
            alice.publish('/s01/rosgate/program', report(user='someone else', name='mine'), STRING)
            got = json.loads(teacher.next_message('/s01/rosgate/program', timeout=WAIT)['data'])
            assert got['user'] == 'alice' and got['name'] == 'mine', got
            # a report that is no JSON object is refused
            refused = alice.refusal({'op': 'publish', 'topic': '/s01/rosgate/program', 'type': STRING,
                                     'msg': {'data': '[1, 2]'}})
            assert refused and 'JSON object' in refused['msg'], refused
            # her live program is hers and the teacher's: not bob's nor a viewer's to read
            for other in (bob, viewer):
                refused = other.refusal({'op': 'subscribe', 'topic': '/s01/rosgate/program', 'type': STRING})
                assert refused and '/s01/rosgate/program' in refused['msg'], refused
            alice.subscribe('/s01/rosgate/program', STRING)
            alice.publish('/s01/rosgate/program', report(name='mine again'), STRING)
            got = json.loads(alice.next_message('/s01/rosgate/program', timeout=WAIT)['data'])
            assert got['name'] == 'mine again' and got['user'] == 'alice', got
            # nor through a recording
            rec = api(school, 'POST', '/api/recordings', {'topics': ['/s01/rosgate/program'], 'max_seconds': 60}, BOB)[1]
            api(school, 'DELETE', f"/api/recordings/{rec['id']}", token=BOB)
            assert api(school, 'GET', f"/api/recordings/{rec['id']}", token=BOB)[1]['topics'] == []
        finally:
            alice.call('/s01/fleet/release', timeout=WAIT)
            bob.call('/s02/fleet/release', timeout=WAIT)


# --- 5. caps per person; an attempt's recording is the teacher's evidence -----------------------------

def test_attempts_are_capped_per_person_with_a_status(school):
    codes = []
    for _ in range(12):
        status, body = api(school, 'POST', '/api/exercises/slow/attempts', {'station': '/s02', 'program': 'p'}, BOB)
        codes.append(status)
        if status == 429:
            assert 'bob' in body['error'] and 'attempts' in body['error'], body
            break
        assert status == 201, body
        stop_attempt(school, body['attempt'], BOB)
    assert codes[-1] == 429 and codes.count(201) <= 6, codes
    # the teacher is not capped
    status, body = api(school, 'POST', '/api/exercises/slow/attempts', {'station': '/s02', 'program': 'p'}, TEACHER)
    assert status == 201, body
    stop_attempt(school, body['attempt'])


def test_an_attempts_recording_is_read_by_its_student_and_kept_for_the_teacher(school):
    attempt = started_attempt(school, ALICE, 'slow', '/s01')
    result = stop_attempt(school, attempt, ALICE)
    rec = result['recording']
    assert rec, result
    assert http(school, f'/api/recordings/{rec}.mcap', token=ALICE).status == 200
    status, body = api(school, 'DELETE', f'/api/recordings/{rec}', token=ALICE)
    assert status == 403 and 'evidence' in body['error'], body
    # listings: a student sees hers, the teacher everyone's
    alices = {r['id'] for r in api(school, 'GET', '/api/recordings', token=ALICE)[1]['recordings']}
    bobs = api(school, 'GET', '/api/recordings', token=BOB)[1]['recordings']
    everyone = {r['id'] for r in api(school, 'GET', '/api/recordings', token=TEACHER)[1]['recordings']}
    assert rec in alices and rec in everyone and rec not in {r['id'] for r in bobs}
    assert all(r['owner'] == 'bob' for r in bobs), bobs
    assert api(school, 'GET', f'/api/recordings/{rec}', token=BOB)[0] == 403
    assert api(school, 'DELETE', f'/api/recordings/{rec}', token=TEACHER)[0] == 204


@pytest.fixture(scope='module')
def small_archive(launch, base):
    """Runs kept in a small archive: 16 KiB in all, 4 KiB a run (a person's share: a quarter)."""
    return launch('--auth', str(base / 'tokens.toml'), '--allow-runs', '--runs-dir', str(base / 'runs-small'),
                  '--run-output-cap', '4K', '--runs-keep-bytes', '16K')


def kept_run(gw, token: str, text: str, times: int) -> str:
    source = f'print({text!r} * {times}, flush=True)\n'
    status, run = api(gw, 'POST', '/api/runs', {'source': source, 'name': 'output'}, token)
    assert status == 201, run
    wait_for(lambda: api(gw, 'GET', f"/api/runs/{run['id']}", token=token)[1]['state'] not in ('starting', 'running'),
             60, 0.1, what='the run ended')
    return run['id']


def test_one_persons_runs_do_not_evict_everyone_elses(small_archive):
    """The runs archive had one budget for all: one person's runs evicted every other person's kept
    runs. Now a person's runs past their share evict their own oldest."""
    alices = kept_run(small_archive, ALICE, 'alice was here. ', 190)   # 3 KB
    bobs = [kept_run(small_archive, BOB, 'bob fills the archive with this line. ', 90) for _ in range(8)]   # 3.4 KB each
    kept = lambda token: {r['id'] for r in api(small_archive, 'GET', '/api/runs?all=1', token=token)[1]['runs']}   # noqa: E731
    wait_for(lambda: bobs[0] not in kept(BOB), WAIT, 0.1, what="bob's oldest run evicted")
    assert alices in kept(ALICE) and alices in kept(TEACHER)
    assert bobs[-1] in kept(BOB)
    assert 'alice was here.' in http(small_archive, f'/api/runs/{alices}/output', token=ALICE).body.decode()


# --- 6. secrets and errors ------------------------------------------------------------------------

def test_no_secret_and_no_server_path_in_an_answer(school, base):
    for token in (VIEWER, ALICE):
        stats = api(school, 'GET', '/api/history/stats', token=token)[1]
        assert stats['db'] == 'sqlite', stats
    teachers = http(school, '/api/history/stats', token=TEACHER)
    assert teachers.status == 200 and PASSWORD.encode() not in teachers.body
    (base / 'gauges.json').write_text('{"battery": {"min": "none"')
    try:
        for token in (VIEWER, ALICE):
            reply = http(school, '/api/gauges', token=token)
            assert reply.status == 500 and str(base).encode() not in reply.body and b'gauges.json' in reply.body, reply
        assert str(base).encode() in http(school, '/api/gauges', token=TEACHER).body   # the admin is told where
    finally:
        (base / 'gauges.json').write_text(json.dumps({'battery': {'min': 0, 'max': 100}}))


def nested(field: str, levels: int) -> bytes:
    """{"field": [[[...0...]]]} nested ``levels`` deep, written out (json.dumps would recurse)."""
    return f'{{"{field}": {"[" * levels}0{"]" * levels}}}'.encode()


@pytest.mark.parametrize('method, path, field', [
    ('POST', '/api/exercises/east/attempts', 'station'), ('POST', '/api/runs', 'source'),
    ('PUT', '/api/programs/deep', 'workspace'), ('POST', '/api/recordings', 'topics'),
    ('POST', '/api/blocks/shared', 'json')])
def test_a_deeply_nested_body_is_a_400_naming_its_field(school, method, path, field):
    for levels in (20_000, 600):
        reply = http(school, path, method=method, data=nested(field, levels), token=TEACHER if 'blocks' in path else ALICE,
                     headers={'Content-Type': 'application/json'})
        assert reply.status == 400, (levels, reply)
        assert b'nested' in reply.body and (levels > 1000 or field.encode() in reply.body), reply
    assert http(school, '/health').status == 200


@pytest.mark.parametrize('query, field', [('from=1e300', 'from'), ('to=1e300', 'to'), ('from=-1e300', 'from'),
                                          ('from=0&to=1e30', 'to'), ('step=1e300', 'step')])
def test_history_with_huge_numbers_is_a_400_naming_them(school, query, field):
    series = wait_for(lambda: [s for s in api(school, 'GET', '/api/history', token=ALICE)[1]['series'] if s['fields']],
                      WAIT, 0.2, what='a topic in the history')
    topic, kept = series[0]['topic'], series[0]['fields'][0]
    status, body = api(school, 'GET', f'/api/history?topic={topic}&field={kept}&{query}', token=ALICE)
    assert status == 400 and f'"{field}"' in body['error'], body


# --- 7. robustness ------------------------------------------------------------------------------

def test_a_symlink_install_workspaces_meshes_are_served_with_its_source_folder(school):
    reply = http(school, '/package/robot_description/meshes/base.stl', token=VIEWER)
    assert reply.status == 200 and reply.body == STL, reply
    for path in ('/package/robot_description/../tokens.toml', '/package/robot_description/%2e%2e/x.stl'):
        assert http(school, path, token=VIEWER).status in (403, 404)


BAD_NAMES = ['/bad name', '/bad\nname', '/a<b>', '/\u202egnp.exe', '/ok/1digit', '/double//slash', '/ümlaut',
             '/trailing/', '/' + 'x' * 300]


@pytest.mark.parametrize('name', BAD_NAMES)
def test_the_sim_refuses_names_ros2_refuses(school, name):
    with Client(school.ws_url, TEACHER) as c:
        for op in ({'op': 'advertise', 'topic': name, 'type': STRING},
                   {'op': 'subscribe', 'topic': name, 'type': STRING},
                   {'op': 'advertise_service', 'service': name, 'type': 'std_srvs/srv/Trigger'}):
            refused = c.refusal(op)
            assert refused and 'no valid ROS 2' in refused['msg'], (op, refused)
        topics = c.call('/rosapi/topics', timeout=WAIT)['values']['topics']
        services = c.call('/rosapi/services', timeout=WAIT)['values']['services']
        assert name not in topics and name not in services
        assert c.refusal({'op': 'advertise', 'topic': '/fine_name_2', 'type': STRING}) is None


@pytest.mark.parametrize('next_', ['/%09/evil.example', '/\t/evil.example', '//evil.example', '/\\evil.example',
                                   'https://evil.example', '/\n/evil.example', '/%0a/evil.example'])
def test_login_sends_back_only_to_a_path_of_this_server(school, next_):
    from urllib.parse import quote, urlencode
    form = urlencode({'token': ALICE, 'next': next_}).encode()
    reply = http(school, '/login', method='POST', data=form)
    assert reply.status == 303 and reply.headers['Location'] == '/', reply.headers['Location']
    assert http(school, '/login?next=' + quote('/class'), method='POST',
                data=urlencode({'token': ALICE, 'next': '/class'}).encode()).headers['Location'] == '/class'
