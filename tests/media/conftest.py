"""Fixtures of the media tests: a gateway with no robot and a test camera publishing to it
(its web_video_server URLs and image subscriptions)."""

from __future__ import annotations

import pytest

from tests.support.camera import running_camera


@pytest.fixture(scope='module')
def cam_gw(start_gateway):
    return start_gateway('--robot', 'none')


@pytest.fixture(scope='module')
def camera(cam_gw):
    """640x480 JPEG CompressedImages at 10 Hz on /cam/image_raw/compressed."""
    with running_camera(cam_gw, '/cam/image_raw/compressed') as cam:
        yield cam
