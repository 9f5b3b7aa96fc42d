"""Runs, recordings and playbacks from outside, against a gateway with --auth --allow-runs
--exclusive-control --fleet 3: they belong to who started them, a playback passes the rules its
person's publishing passes (the driver lease, the teacher's stop, the name globs), a recording
holds only what a client could subscribe to, and nobody holds every recording slot."""

from __future__ import annotations


import pytest

from tests.support.auth import TOKENS
from tests.support.http import api, http
from tests.support.wait import wait_for
from tests.support.wsclient import TWIST, Client, is_zero_twist, twist

POSE = 'turtlesim/msg/Pose'
S01 = '/s01/turtle1/cmd_vel'
SLEEPER = 'import time\ntime.sleep(120)\n'


@pytest.fixture(scope='module')
def school(launch, tokens_file, tmp_path_factory):
    folder = tmp_path_factory.mktemp('school')
    return launch('--robot', 'turtlesim', '--fleet', '3', '--auth', tokens_file, '--allow-runs',
                  '--exclusive-control', '--runs-dir', str(folder / 'runs'), '--record', str(folder / 'rec'),
                  '--record-topics', '/s03/turtle1/color_sensor', '--cmd-timeout', '0')


def recording(gw, who: str, topics: list, seconds: float = 600) -> dict:
    status, body = api(gw, 'POST', '/api/recordings', {'topics': topics, 'max_seconds': seconds}, TOKENS[who])
    assert status == 201, body
    return body


def finished(gw, rec_id: str) -> dict:
    return wait_for(lambda: (lambda b: b if b['state'] != 'recording' else None)(
        api(gw, 'GET', f'/api/recordings/{rec_id}', token=TOKENS['admin'])[1]), 30, 0.05)


def download(gw, rec_id: str, who: str) -> int:
    return http(gw, f'/api/recordings/{rec_id}.mcap', token=TOKENS[who]).status


def listed(gw, rec_id: str) -> dict | None:
    """A recording as the teacher's listing shows it (a student's shows her own alone)."""
    recs = api(gw, 'GET', '/api/recordings', token=TOKENS['admin'])[1]['recordings']
    return next((r for r in recs if r['id'] == rec_id), None)


def test_another_operators_run_cannot_be_stopped(school):
    status, body = api(school, 'POST', '/api/runs', {'source': SLEEPER, 'name': 'alices', 'ns': '/s02'},
                       TOKENS['operator'])
    assert status == 201, body
    run_id = body['id']
    wait_for(lambda: api(school, 'GET', f'/api/runs/{run_id}', token=TOKENS['admin'])[1]['state'] == 'running', 30)
    status, body = api(school, 'DELETE', f'/api/runs/{run_id}', token=TOKENS['operator2'])
    assert status == 403 and 'alice' in body['error'], body
    assert api(school, 'GET', f'/api/runs/{run_id}', token=TOKENS['admin'])[1]['state'] == 'running'
    status, body = api(school, 'DELETE', f'/api/runs/{run_id}', token=TOKENS['operator'])
    assert status in (200, 202), body
    wait_for(lambda: api(school, 'GET', f'/api/runs/{run_id}', token=TOKENS['admin'])[1]['state'] == 'stopped', 30)


def test_another_operators_recording_cannot_be_stopped_played_downloaded_or_deleted(school):
    running = recording(school, 'operator', ['/s02/turtle1/pose'])
    status, body = api(school, 'DELETE', f"/api/recordings/{running['id']}", token=TOKENS['operator2'])
    assert status == 403 and 'alice' in body['error'], body
    assert listed(school, running['id'])['state'] == 'recording'
    wait_for(lambda: listed(school, running['id'])['messages'] >= 50, 20)   # a second or so, to play slowly
    assert api(school, 'DELETE', f"/api/recordings/{running['id']}", token=TOKENS['operator'])[0] == 200
    rec_id = finished(school, running['id'])['id']
    assert listed(school, rec_id)['owner'] == 'alice'

    assert api(school, 'POST', f'/api/recordings/{rec_id}/play', {'prefix': '/bobs'}, TOKENS['operator2'])[0] == 403
    assert api(school, 'POST', f'/api/recordings/{rec_id}/play', token=TOKENS['operator2'])[0] == 403   # empty body
    assert download(school, rec_id, 'operator2') == 403
    assert api(school, 'DELETE', f'/api/recordings/{rec_id}', token=TOKENS['operator2'])[0] == 403
    assert listed(school, rec_id) is not None
    assert download(school, rec_id, 'operator') == 200 and download(school, rec_id, 'admin') == 200

    # alice's playback is alice's to stop (and the teacher's)
    status, body = api(school, 'POST', f'/api/recordings/{rec_id}/play', {'prefix': '/alices', 'rate': 0.05},
                       TOKENS['operator'])
    assert status == 202, body
    assert api(school, 'DELETE', f'/api/recordings/{rec_id}/play', token=TOKENS['operator2'])[0] == 403
    assert listed(school, rec_id)['playing'] is True
    assert api(school, 'DELETE', f'/api/recordings/{rec_id}/play', token=TOKENS['admin'])[1] == {'stopped': True}
    assert api(school, 'DELETE', f'/api/recordings/{rec_id}', token=TOKENS['operator'])[0] == 204
    assert listed(school, rec_id) is None


def test_one_person_holds_at_most_two_recordings_at_once(school):
    mine = [recording(school, 'operator', ['/s02/turtle1/pose'])['id'] for _ in range(2)]
    try:
        status, body = api(school, 'POST', '/api/recordings', {'topics': ['/s02/turtle1/pose']}, TOKENS['operator'])
        assert status == 429 and 'alice' in body['error'], body   # refused before all 4 slots are hers
        bobs = recording(school, 'operator2', ['/s02/turtle1/pose'])['id']   # someone else still gets one
        mine.append(bobs)
    finally:
        for rec_id in mine:
            api(school, 'DELETE', f'/api/recordings/{rec_id}', token=TOKENS['admin'])


def drive_and_record(gw) -> str:
    """Alice drives /s01 for a moment and stops, recorded: a bag with moving commands, the zero,
    then poses; she gives the lease back."""
    with Client(gw.ws_url, TOKENS['operator']) as alice:
        rec = recording(gw, 'operator', [S01, '/s01/turtle1/pose'])
        for i in range(10):
            alice.publish(S01, twist(0.2), TWIST)
        alice.publish(S01, twist(), TWIST)
        alice.sync()
        wait_for(lambda: listed(gw, rec['id'])['messages'] >= 100, 20)   # poses after the commands
        api(gw, 'DELETE', f"/api/recordings/{rec['id']}", token=TOKENS['operator'])
        alice.publish('/rosgate/control', {'data': 'release'})
        alice.sync()
    return finished(gw, rec['id'])['id']


def test_playback_into_a_station_someone_else_drives_is_refused_up_front(school):
    rec_id = drive_and_record(school)
    with Client(school.ws_url, TOKENS['viewer']) as watcher, Client(school.ws_url, TOKENS['operator2']) as bob:
        watcher.subscribe(S01, TWIST)
        bob.publish(S01, twist(0.1), TWIST)   # bob drives /s01 now
        assert watcher.next_message(S01) == twist(0.1)
        status, body = api(school, 'POST', f'/api/recordings/{rec_id}/play', token=TOKENS['operator'])
        assert status == 409 and 'bob' in body['error'] and '/s01' in body['error'], body
        assert listed(school, rec_id)['playing'] is False
        bob.publish(S01, twist(), TWIST)
        bob.sync()
        watcher.sync()
        got = [m for m in watcher.seen if m.get('op') == 'publish' and m.get('topic') == S01]
        assert got == [{'op': 'publish', 'topic': S01, 'msg': twist()}], got   # bob's zero; nothing of alice's bag


def test_the_teachers_stop_ends_a_playback_in_that_station(school):
    rec_id = drive_and_record(school)
    with Client(school.ws_url, TOKENS['viewer']) as watcher, Client(school.ws_url, TOKENS['admin']) as teacher:
        watcher.subscribe(S01, TWIST)
        status, body = api(school, 'POST', f'/api/recordings/{rec_id}/play', {'rate': 0.2}, TOKENS['operator'])
        assert status == 202, body    # a bag of a few seconds, played five times slower
        assert watcher.next_message(S01, lambda m: not is_zero_twist(m), timeout=10) == twist(0.2)
        teacher.publish('/rosgate/control', {'data': 'stop /s01'})
        teacher.sync()
        wait_for(lambda: listed(school, rec_id)['playing'] is False, 3)   # long before the bag would end
        assert api(school, 'DELETE', f'/api/recordings/{rec_id}/play', token=TOKENS['operator'])[1] == {'stopped': False}


@pytest.fixture(scope='module')
def globbed(launch):
    return launch('--robot', 'turtlesim', '--talker', '--topics-glob', "['/turtle1/pose','/rosout']")


def test_recordings_hold_only_what_the_globs_show_and_play_only_where_a_client_may_publish(globbed):
    status, body = api(globbed, 'POST', '/api/recordings', {'topics': ['/*'], 'max_seconds': 1})
    assert status == 201, body
    done = finished(globbed, body['id'])
    assert '/turtle1/pose' in done['topics'], done
    assert set(done['topics']) <= {'/turtle1/pose', '/rosout'}, done   # no /chatter, no /turtle1/cmd_vel
    status, body = api(globbed, 'POST', f"/api/recordings/{done['id']}/play", {'prefix': '/replay'})
    assert status == 403 and 'cannot play into /replay/' in body['error'], body
    assert listed(globbed, done['id'])['playing'] is False


def test_one_person_fills_at_most_32_mib_of_library(school):
    pad = 'x' * (2 * 2**20 - 200)   # a program just under the 2 MiB a program may be
    saved, refused = 0, None
    for i in range(20):
        status, body = api(school, 'PUT', f'/api/programs/big{i}', {'format': 'rosgate-program', 'pad': pad},
                           TOKENS['operator'])
        if status != 200:
            refused = (i, status, body)
            break
        saved += 1
    assert refused is not None and refused[1] in (413, 507), refused
    assert saved * len(pad) <= 32 * 2**20 and saved >= 15, saved   # refused before 32 MiB, not long before
    listing = api(school, 'GET', '/api/programs', token=TOKENS['operator'])[1]['programs']
    assert len(listing) == saved
    # someone else still saves; replacing one of alice's programs with a smaller one still works
    assert api(school, 'PUT', '/api/programs/small', {'format': 'rosgate-program'}, TOKENS['operator2'])[0] == 200
    assert api(school, 'PUT', '/api/programs/big0', {'format': 'rosgate-program'}, TOKENS['operator'])[0] == 200
    for i in range(saved):
        api(school, 'DELETE', f'/api/programs/big{i}', token=TOKENS['operator'])
