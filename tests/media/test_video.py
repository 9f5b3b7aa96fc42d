"""web_video_server's URLs on the gateway's port, against a live gateway: a roslibpy camera
(640x480 JPEG CompressedImage, 10 Hz) and the sim rover's camera, read by raw sockets."""

from __future__ import annotations

import io
import os
import time
import urllib.error
import urllib.request

import pytest
from PIL import Image

from tests.support.camera import BOUNDARY, Stream, stream_head
from tests.support.http import http
from tests.support.process import proc_bytes
from tests.support.ros import client
from tests.support.wait import wait_for

BASE = '/cam/image_raw'


def health(gw) -> dict:
    return http(gw, '/health').json()


def size_of(jpeg: bytes) -> tuple[int, int]:
    return Image.open(io.BytesIO(jpeg)).size


def fds(pid: int) -> int:
    return len(os.listdir(f'/proc/{pid}/fd'))


def test_stream_is_web_video_servers_wire_format(cam_gw, camera):
    s = Stream(cam_gw.port, f'/stream?topic={BASE}')
    try:
        assert s.head == stream_head(cors=True)
        assert s.opening() == b'--' + BOUNDARY + b'\r\n'
        stamps = []
        for _ in range(3):
            kind, stamp, data = s.part()   # each part's headers and boundary checked byte for byte
            assert kind == 'image/jpeg'
            assert stamp in camera.sent    # X-Timestamp: the message's header stamp, %.06f
            assert size_of(data) == (640, 480)
            stamps.append(float(stamp))
        assert stamps == sorted(stamps) and len(set(stamps)) == 3
    finally:
        s.close()


def test_ros_compressed_passes_the_topics_bytes(cam_gw, camera):
    s = Stream(cam_gw.port, f'/stream?topic={BASE}&type=ros_compressed')
    try:
        assert s.head == stream_head(cors=True)
        s.opening()
        for _ in range(3):
            kind, stamp, data = s.part()
            assert kind == 'image/jpeg'
            assert data == camera.sent[stamp]   # the very bytes published, not re-encoded
    finally:
        s.close()


def test_size_and_quality_and_png(cam_gw, camera):
    s = Stream(cam_gw.port, f'/stream?topic={BASE}&width=320&height=240&quality=40')
    try:
        s.opening()
        kind, stamp, small = s.part()
        assert kind == 'image/jpeg' and size_of(small) == (320, 240)
        assert len(small) < len(camera.sent[stamp]) / 3
    finally:
        s.close()
    s = Stream(cam_gw.port, f'/stream?topic={BASE}&type=png&width=64&height=48')
    try:
        s.opening()
        kind, _, data = s.part()
        assert kind == 'image/png' and data[:8] == b'\x89PNG\r\n\x1a\n' and size_of(data) == (64, 48)
    finally:
        s.close()


def test_snapshot(cam_gw, camera):
    s = Stream(cam_gw.port, f'/snapshot?topic={BASE}&width=160&height=120')
    try:
        body = s.rest()   # Connection: close, as web_video_server
    finally:
        s.close()
    head = s.head.decode()
    lines = head.split('\r\n')
    assert lines[0] == 'HTTP/1.0 200 OK'
    names = [line.split(':')[0] for line in lines[1:] if line]
    assert names == ['Connection', 'Server', 'Cache-Control', 'X-Timestamp', 'Pragma', 'Content-type',
                     'Access-Control-Allow-Origin', 'Content-Length']
    assert 'Content-type: image/jpeg\r\n' in head
    assert f'Content-Length: {len(body)}\r\n' in head
    stamp = next(line.split(': ')[1] for line in lines if line.startswith('X-Timestamp'))
    assert stamp in camera.sent
    assert size_of(body) == (160, 120)


def test_viewer_and_list_pages(cam_gw, camera):
    s = Stream(cam_gw.port, f'/stream_viewer?topic={BASE}&type=mjpeg&width=320')
    try:
        page = s.head + s.rest()
    finally:
        s.close()
    assert page == (b'HTTP/1.0 200 OK\r\nConnection: close\r\nServer: web_video_server\r\nContent-type: text/html;\r\n\r\n'
                    b'<html><head><title>/cam/image_raw</title></head><body><h1>/cam/image_raw</h1>'
                    b'<img src="/stream?topic=/cam/image_raw&type=mjpeg&width=320"></img></body></html>')
    s = Stream(cam_gw.port, '/streams')
    try:
        page = s.head + s.rest()
    finally:
        s.close()
    assert page.startswith(b'HTTP/1.0 200 OK\r\nConnection: close\r\nServer: web_video_server\r\n')
    assert (b'<html><head><title>ROS Image Topic List</title></head><body><h1>Available ROS Image Topics:</h1>'
            in page)
    # a base topic with only /compressed is listed under its base name, which /stream serves
    assert (b'<li><a href="/stream_viewer?topic=/cam/image_raw">/cam/image_raw</a> '
            b'(<a href="/stream?topic=/cam/image_raw">Stream</a>) '
            b'(<a href="/snapshot?topic=/cam/image_raw">Snapshot</a>)</li>') in page
    # an attribute cannot be closed from the query
    s = Stream(cam_gw.port, '/stream_viewer?topic=/a%22%3E&x="><script>')
    try:
        page = s.rest()
    finally:
        s.close()
    assert b'<script>' not in page
    assert page.split(b'<img src="')[1].split(b'"')[0] == b'/stream?topic=/a%22%3E&x=%22%3E%3Cscript%3E'
    assert b'<title>/a&quot;&gt;</title>' in page


def test_unknown_topic_is_answered_within_5_s(cam_gw):
    started = time.monotonic()
    with pytest.raises(urllib.error.HTTPError) as e:
        urllib.request.urlopen(cam_gw.http_url + 'stream?topic=/no/such/camera', timeout=10)
    assert e.value.code == 404 and b'no image topic /no/such/camera' in e.value.read()
    assert time.monotonic() - started < 5
    with pytest.raises(urllib.error.HTTPError) as e:   # a topic that is not an image
        urllib.request.urlopen(cam_gw.http_url + 'snapshot?topic=/client_count', timeout=10)
    assert e.value.code == 404 and b'not an image topic' in e.value.read()
    for bad, code in (('stream?topic=/cam/image_raw&type=vp9', 404), ('stream?type=mjpeg', 400),
                      ('stream?topic=/cam/image_raw&width=abc', 400), ('snapshot?topic=/x&quality=500', 400)):
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(cam_gw.http_url + bad, timeout=10)
        assert e.value.code == code, bad


def test_slow_reader_gets_fresh_frames(cam_gw, camera):
    """A viewer that stops reading for 3 s gets, once it reads again, the newest frame: no
    backlog of the frames published during its pause."""
    pause = 3.0
    s = Stream(cam_gw.port, f'/stream?topic={BASE}', rcvbuf=16384)
    try:
        s.opening()
        s.part()
        time.sleep(pause)   # the reader's own pause: what this test is about
        ages = []
        for _ in range(3):
            _, stamp, _ = s.part()
            ages.append(time.time() - float(stamp))
        # the frame being written when the pause began is as old as the pause; the next ones are fresh
        assert ages[0] < pause + 1.0, ages
        assert max(ages[1:]) < 1.0, ages
    finally:
        s.close()


def test_twelve_viewers_cost_one_encode_per_frame(cam_gw, camera):
    streams = [Stream(cam_gw.port, f'/stream?topic={BASE}&width=200&height=150&quality=70') for _ in range(12)]
    try:
        for s in streams:
            s.opening()
            s.part()
        before, published = health(cam_gw)['images_rendered'], camera.count
        seen = set()
        for _ in range(5):
            for s in streams:
                seen.add(s.part()[1])
        rendered = health(cam_gw)['images_rendered'] - before
        frames = camera.count - published
        assert rendered <= frames + 1, (rendered, frames)   # one per frame, not one per viewer
        assert len(seen) >= 5
    finally:
        for s in streams:
            s.close()


def test_abandoned_streams_leave_nothing_behind(cam_gw, camera):
    baseline_topics = health(cam_gw)['topics']
    warm = [Stream(cam_gw.port, f'/stream?topic={BASE}&width={w}') for w in (100, 101)]
    for s in warm:
        s.opening()
        s.part()
        s.close()
    wait_for(lambda: health(cam_gw)['topics'] == baseline_topics, 10)
    fd_before, rss_before = fds(cam_gw.pid), proc_bytes(cam_gw.pid)
    for i in range(50):
        s = Stream(cam_gw.port, f'/stream?topic={BASE}&width={100 + i % 5}', rcvbuf=8192)
        s.opening()
        s.part()
        s.close()   # gone without a word, mid-stream
    wait_for(lambda: fds(cam_gw.pid) <= fd_before, 15)
    wait_for(lambda: health(cam_gw)['topics'] == baseline_topics, 15)   # the backend subscription released
    assert proc_bytes(cam_gw.pid) - rss_before < 16 * 2**20


def test_rover_camera_by_its_base_topic(start_gateway):
    gw = start_gateway('--robot', 'rover', '--history', 'none')   # nothing else of the gateway's subscribes
    s = Stream(gw.port, '/stream?topic=/camera/image_raw&type=ros_compressed')
    try:
        assert s.head == stream_head(cors=True)
        s.opening()
        kind, stamp, data = s.part()
        assert kind == 'image/jpeg' and size_of(data) == (160, 120)
    finally:
        s.close()
    wait_for(lambda: health(gw)['topics'] == 0, 10)


def test_a_silent_camera_gets_an_answer_too(cam_gw):
    """A camera topic that exists but sends nothing: a snapshot says so within 5 s (504)."""
    import roslibpy
    with client(cam_gw) as ros:
        topic = roslibpy.Topic(ros, '/silent/image_raw/compressed', 'sensor_msgs/msg/CompressedImage')
        topic.advertise()
        try:
            wait_for(lambda: '/silent/image_raw/compressed' in ros.get_topics(), 10)
            started = time.monotonic()
            with pytest.raises(urllib.error.HTTPError) as e:
                urllib.request.urlopen(cam_gw.http_url + 'snapshot?topic=/silent/image_raw', timeout=10)
            assert e.value.code == 504 and b'no image on /silent/image_raw/compressed' in e.value.read()
            assert time.monotonic() - started < 5
        finally:
            topic.unadvertise()
