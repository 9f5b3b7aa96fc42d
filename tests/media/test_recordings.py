"""Recordings (/api/recordings): MCAP rosbag2 files of live topics, read back with the rosbags
and mcap readers, and played back into the graph with the recorded timing."""

from __future__ import annotations

import io
import queue
import time
from pathlib import Path

import pytest
import roslibpy

from tests.support.http import api
from tests.support.ros import client as connect
from tests.support.wait import wait_for

POSE = 'turtlesim/msg/Pose'


@pytest.fixture(scope='module')
def rec_gw(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('recordings')
    gw = start_gateway('--robot', 'turtlesim', '--record', str(folder), '--record-topics', '/turtle1/color_sensor')
    gw.folder = folder
    return gw


@pytest.fixture
def client(rec_gw):
    with connect(rec_gw) as ros:
        yield ros


def record(gw, topics, seconds) -> dict:
    status, body = api(gw, 'POST', '/api/recordings', {'topics': topics, 'max_seconds': seconds})
    assert status == 201, body
    return wait_for(lambda: (lambda b: b if b['state'] != 'recording' else None)(
        api(gw, 'GET', f"/api/recordings/{body['id']}")[1]), seconds + 30, 0.05)


def sync(ros) -> None:
    """A round trip on this connection: the ops sent before it (subscribe) have been handled."""
    roslibpy.Service(ros, '/rosapi/topics', 'rosapi/Topics').call(roslibpy.ServiceRequest({}), timeout=10)


def download(gw, rec_id: str) -> bytes:
    import urllib.request
    with urllib.request.urlopen(f'{gw.http_url}api/recordings/{rec_id}.mcap', timeout=10) as res:
        assert res.headers['Content-Type'] == 'application/octet-stream'
        return res.read()


def test_three_seconds_of_pose_open_in_the_readers_and_play_back_in_time(rec_gw, client, tmp_path):
    body = record(rec_gw, ['/turtle1/pose'], 3)
    assert body['state'] == 'done' and 'max_seconds' in body['reason'], body
    assert body['topics'] == ['/turtle1/pose']

    # rosbags opens the bag directory the gateway wrote ...
    from rosbags.highlevel import AnyReader
    with AnyReader([rec_gw.folder / body['id']]) as reader:
        stamps, poses = [], []
        for conn, stamp, raw in reader.messages():
            assert (conn.topic, conn.msgtype) == ('/turtle1/pose', POSE)
            poses.append(reader.deserialize(raw, conn.msgtype))
            stamps.append(stamp)
    assert len(stamps) >= 150
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert 2.5 < (stamps[-1] - stamps[0]) / 1e9 < 3.5
    assert all(isinstance(p.x, float) and 0 < p.x < 12 for p in poses)
    print(f'recorded {len(stamps)} messages over {(stamps[-1] - stamps[0]) / 1e9:.3f} s')

    # ... and the downloaded file alone opens in the mcap reader, definitions included
    data = download(rec_gw, body['id'])
    assert len(data) == body['bytes']
    try:
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory
    except ImportError:   # the mcap readers are test extras; rosbags (above) always reads it
        make_reader = None
    if make_reader is not None:
        reader = make_reader(io.BytesIO(data), decoder_factories=[DecoderFactory()])
        decoded = [(ch.topic, sc.name, m.log_time, msg.x) for sc, ch, m, msg in reader.iter_decoded_messages()]
        assert len(decoded) == len(stamps)
        assert {(t, n) for t, n, _, _ in decoded} == {('/turtle1/pose', POSE)}
        assert [d[2] for d in decoded] == stamps
        assert reader.get_header().profile == 'ros2'

    # playing it back under a prefix republishes every message with the recorded spacing
    got: queue.Queue = queue.Queue()
    roslibpy.Topic(client, '/replay/turtle1/pose', POSE).subscribe(lambda m: got.put((time.monotonic(), m)))
    sync(client)
    status, play = api(rec_gw, 'POST', f"/api/recordings/{body['id']}/play", {'rate': 1.0, 'prefix': '/replay'})
    assert status == 202, play
    assert play['messages'] == len(stamps)
    arrivals = []
    while len(arrivals) < len(stamps):
        arrivals.append(got.get(timeout=10))
    played = arrivals[-1][0] - arrivals[0][0]
    recorded = (stamps[-1] - stamps[0]) / 1e9
    error = abs(played - recorded) / recorded
    print(f'played {len(arrivals)} messages over {played:.3f} s (recorded {recorded:.3f} s): {error * 100:.2f} % off')
    assert error < 0.10
    assert [m['x'] for _, m in arrivals] == pytest.approx([p.x for p in poses])


def test_rate_plays_faster(rec_gw, client):
    body = record(rec_gw, ['/turtle1/pose'], 1)
    got: queue.Queue = queue.Queue()
    roslibpy.Topic(client, '/fast/turtle1/pose', POSE).subscribe(lambda m: got.put(time.monotonic()))
    sync(client)
    status, play = api(rec_gw, 'POST', f"/api/recordings/{body['id']}/play", {'rate': 4, 'prefix': '/fast'})
    assert status == 202, play
    times = [got.get(timeout=10) for _ in range(play['messages'])]
    assert (times[-1] - times[0]) < play['duration'] / 4 * 1.5


def test_start_up_recording_and_listing(rec_gw):
    status, body = api(rec_gw, 'GET', '/api/recordings')
    assert status == 200
    startup = [r for r in body['recordings'] if r.get('requested') == ['/turtle1/color_sensor']]
    assert startup and startup[0]['state'] == 'recording'
    wait_for(lambda: api(rec_gw, 'GET', f"/api/recordings/{startup[0]['id']}")[1]['messages'] > 10)
    assert api(rec_gw, 'GET', f"/api/recordings/{startup[0]['id']}.mcap")[0] == 409   # still recording


def test_stop_delete_and_bad_requests(rec_gw):
    status, body = api(rec_gw, 'POST', '/api/recordings', {'topics': ['/turtle1/pose'], 'max_seconds': 60})
    assert status == 201
    rec_id = body['id']
    wait_for(lambda: api(rec_gw, 'GET', f'/api/recordings/{rec_id}')[1]['messages'] > 5)
    status, body = api(rec_gw, 'DELETE', f'/api/recordings/{rec_id}')
    assert status == 200 and body['state'] == 'done' and body['reason'] == 'stopped'
    assert (Path(rec_gw.folder) / rec_id / f'{rec_id}.mcap').is_file()
    assert api(rec_gw, 'DELETE', f'/api/recordings/{rec_id}')[0] == 204
    assert not (Path(rec_gw.folder) / rec_id).exists()
    for bad in ({}, {'topics': 'x'}, {'topics': ['no-slash']}, {'topics': ['/a'], 'max_seconds': 0}):
        status, body = api(rec_gw, 'POST', '/api/recordings', bad)
        assert status == 400, body
    for path in ('/api/recordings/..%2F..%2Fetc.mcap', '/api/recordings/rec-x.mcap', '/api/recordings/nope'):
        assert api(rec_gw, 'GET', path)[0] == 404


def test_at_most_n_at_once(rec_gw):
    started = []
    try:
        while True:
            status, body = api(rec_gw, 'POST', '/api/recordings', {'topics': ['/turtle1/pose'], 'max_seconds': 30})
            if status != 201:
                break
            started.append(body['id'])
        assert status == 409 and 'already running' in body['error']
        assert 1 <= len(started) <= 4
    finally:
        for rec_id in started:
            api(rec_gw, 'DELETE', f'/api/recordings/{rec_id}')


def test_recordings_dir_without_recording_from_start_up(start_gateway, tmp_path):
    """--recordings-dir says where recordings go and records nothing by itself (--record does both)."""
    folder = tmp_path / 'class recordings'
    gw = start_gateway('--robot', 'turtlesim', '--recordings-dir', str(folder))
    assert api(gw, 'GET', '/api/recordings')[1]['recordings'] == []
    done = record(gw, ['/turtle1/pose'], 0.5)
    assert done['state'] == 'done', done
    assert len(list(folder.rglob('*.mcap'))) == 1
