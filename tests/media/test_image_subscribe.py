"""The ``image`` extension field of subscribe: a smaller or rougher JPEG of an image topic,
rendered once per (topic, size, quality) for every subscriber that asks for it."""

from __future__ import annotations

import base64
import io
import time

import pytest
import roslibpy
from PIL import Image

from tests.bench.camera import ws_client, ws_stamps
from tests.support.http import http
from tests.support.rawclient import Raw
from tests.support.ros import client

TOPIC = '/cam/image_raw/compressed'


def rendered(cam_gw) -> int:
    return http(cam_gw, '/health').json()['images_rendered']


def image_of(msg: dict) -> Image.Image:
    data = msg['msg']['data']
    return Image.open(io.BytesIO(base64.b64decode(data) if isinstance(data, str) else data))


def is_publish(msg: dict) -> bool:
    return msg.get('op') == 'publish'


@pytest.mark.parametrize('compression', ['none', 'cbor'])
def test_a_smaller_jpeg_on_request(cam_gw, camera, compression):
    c = Raw(cam_gw.ws_url)
    try:
        c.send({'op': 'subscribe', 'topic': TOPIC, 'id': 'small', 'compression': compression,
                'image': {'width': 320, 'quality': 50}})
        msg = c.expect(is_publish, 10)
        assert msg['msg']['format'] == 'jpeg'
        img = image_of(msg)
        assert img.format == 'JPEG' and img.size == (320, 240)   # the missing side follows the aspect
        assert msg['msg']['header']['frame_id'] == 'cam'
        original = max(len(b) for b in camera.images)
        assert len(base64.b64decode(msg['msg']['data']) if compression == 'none' else msg['msg']['data']) < original / 3
    finally:
        c.ws.close()


def test_one_render_per_size_for_all_subscribers(cam_gw, camera):
    clients = [Raw(cam_gw.ws_url) for _ in range(6)]
    try:
        for i, c in enumerate(clients):
            c.send({'op': 'subscribe', 'topic': TOPIC, 'id': f's{i}', 'image': {'width': 160, 'height': 120,
                                                                              'quality': 40}})
        for c in clients:
            c.expect(is_publish, 10)
        before, published = rendered(cam_gw), camera.count
        for _ in range(4):
            for c in clients:
                assert image_of(c.expect(is_publish, 10)).size == (160, 120)
        frames = camera.count - published
        assert rendered(cam_gw) - before <= frames + 1, (rendered(cam_gw) - before, frames)
    finally:
        for c in clients:
            c.ws.close()


def test_a_raw_image_topic(cam_gw):
    with client(cam_gw) as ros:
        topic = roslibpy.Topic(ros, '/raw/image', 'sensor_msgs/msg/Image')
        topic.advertise()
        c = Raw(cam_gw.ws_url)
        try:
            c.send({'op': 'subscribe', 'topic': '/raw/image', 'type': 'sensor_msgs/msg/Image',
                    'image': {'width': 32}})
            pixels = bytes([200, 10, 10] * (64 * 48))   # bgr8: a red image once read as BGR
            msg = None
            for _ in range(50):
                topic.publish(roslibpy.Message({'header': {'frame_id': 'raw'}, 'height': 48, 'width': 64,
                                                'encoding': 'bgr8', 'is_bigendian': 0, 'step': 64 * 3,
                                                'data': base64.b64encode(pixels).decode()}))
                try:
                    msg = c.expect(is_publish, 0.2)
                    break
                except AssertionError:
                    continue
            assert msg is not None
            img = image_of(msg).convert('RGB')
            assert img.size == (32, 24)
            r, g, b = img.getpixel((16, 12))
            assert r < 40 and b > 160   # channels swapped from BGR
        finally:
            c.ws.close()
            topic.unadvertise()


def test_refused_where_it_does_not_apply(cam_gw, camera):
    c = Raw(cam_gw.ws_url)
    try:
        c.send({'op': 'subscribe', 'topic': '/client_count', 'id': 'not-image', 'image': {'width': 10}})
        status = c.expect(lambda m: m.get('op') == 'status', 5)
        assert status['level'] == 'error' and status['id'] == 'not-image'
        assert "'image' applies to sensor_msgs/msg/Image, sensor_msgs/msg/CompressedImage, nav_msgs/msg/OccupancyGrid" in status['msg']
        c.send({'op': 'subscribe', 'topic': TOPIC, 'id': 'raw', 'compression': 'cbor-raw', 'image': {}})
        status = c.expect(lambda m: m.get('op') == 'status', 5)
        assert status['id'] == 'raw' and 'cbor-raw' in status['msg']
        c.send({'op': 'subscribe', 'topic': TOPIC, 'id': 'bad', 'image': {'width': 0}})
        status = c.expect(lambda m: m.get('op') == 'status', 5)
        assert status['id'] == 'bad' and "field 'image' 'width' must be an integer from 1" in status['msg']
    finally:
        c.ws.close()


@pytest.mark.parametrize('options', [{}, {'throttle_rate': 200, 'queue_length': 1}])
def test_a_client_that_falls_behind_gets_the_newest_frame(cam_gw, camera, options):
    """Sensor streams are newest-wins and the kernel's unsent share is small: a websocket client
    that stops reading for 3 s finds a few frames from its pause, then fresh ones, not a backlog
    (before: the default queue held 100 frames and the kernel ~400 KiB)."""
    c = ws_client(cam_gw.port, None, {'op': 'subscribe', 'topic': TOPIC, 'type': 'sensor_msgs/msg/CompressedImage',
                                  **options})
    try:
        stamps = ws_stamps(c)
        next(stamps)
        time.sleep(3.0)   # the client's own pause: what this test is about
        ages = []
        for stamp in stamps:
            ages.append(time.time() - stamp)
            if len(ages) >= 10:
                break
        stale = [a for a in ages if a > 1.0]
        assert len(stale) <= 5, ages   # what was already in the buffers when the pause began
        assert max(ages[-3:]) < 1.0, ages
    finally:
        c.sock.close()


def test_an_image_already_small_enough_passes_unchanged(cam_gw, camera):
    """Asked for more than the camera gives, the gateway sends the camera's own JPEG (never
    enlarged, and not re-encoded: re-encoding costs the event loop for a few bytes)."""
    c = Raw(cam_gw.ws_url)
    try:
        c.send({'op': 'subscribe', 'topic': TOPIC, 'id': 'big', 'image': {'width': 1000, 'quality': 30}})
        for _ in range(3):
            msg = c.expect(is_publish, 10)
            stamp = msg['msg']['header']['stamp']
            key = '%.06f' % ((stamp['sec'] * 10**9 + stamp['nanosec']) / 1e9)
            assert base64.b64decode(msg['msg']['data']) == camera.sent[key]
    finally:
        c.ws.close()
