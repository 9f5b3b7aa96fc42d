"""web_video_server's URLs on the rclpy backend: a plain rclpy node publishes 640x480 JPEG
CompressedImages; /stream passes their bytes (ros_compressed) or re-encodes them (mjpeg)."""

from __future__ import annotations

import asyncio
import io

import pytest
from PIL import Image

from tests.support.camera import Stream, frames, stream_head
from tests.support.contract import rclpy_missing
from tests.support.wait import until

pytestmark = [
    pytest.mark.asyncio(loop_scope='session'),
    pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here'),
]


@pytest.fixture(scope='module')
def gateway(rclpy_helpers, start_gateway):
    return start_gateway('--backend', 'rclpy')


async def test_stream_of_an_rclpy_camera(gateway, caller):
    from sensor_msgs.msg import CompressedImage
    publish = caller.publisher(CompressedImage, '/rclpy_cam/image_raw/compressed', 10)
    images = frames(4)
    sent: dict[str, bytes] = {}
    halt = asyncio.Event()

    async def camera() -> None:
        n = 0
        while not halt.is_set():
            msg = CompressedImage(format='jpeg', data=images[n % len(images)])
            msg.header.stamp.sec, msg.header.stamp.nanosec = 1000 + n, 500_000_000
            sent['%.06f' % (1000 + n + 0.5)] = images[n % len(images)]
            publish(msg)
            n += 1
            await asyncio.sleep(0.1)

    task = asyncio.ensure_future(camera())

    def listed() -> bool:
        s = Stream(gateway.port, '/streams')
        try:
            return b'/rclpy_cam/image_raw' in s.rest()
        finally:
            s.close()

    def read(query: str, count: int) -> tuple[bytes, list]:
        s = Stream(gateway.port, f'/stream?{query}', timeout=30)
        try:
            s.opening()
            return s.head, [s.part() for _ in range(count)]
        finally:
            s.close()
    try:
        await until(lambda: listed(), what='DDS discovery of the camera', timeout=30)
        head, parts = await asyncio.to_thread(read, 'topic=/rclpy_cam/image_raw&type=ros_compressed', 3)
        assert head == stream_head(cors=True)
        for kind, stamp, data in parts:
            assert kind == 'image/jpeg' and data == sent[stamp]
        _, parts = await asyncio.to_thread(read, 'topic=/rclpy_cam/image_raw&width=320&height=240', 2)
        for kind, stamp, data in parts:
            assert stamp in sent and Image.open(io.BytesIO(data)).size == (320, 240)
    finally:
        halt.set()
        await task
