"""The teleop page's camera over the subscribe extension ``image``: a 640x480 camera arrives
as the smaller JPEG the page asks for, with the frame's age shown beside it."""

from __future__ import annotations

from tests.support.camera import Camera
from tests.support.ide import open_teleop
from tests.support.ros import client
from tests.support.wait import wait_for


def test_teleop_asks_for_a_smaller_image_and_shows_its_age(chromium, start_gateway):
    gw = start_gateway('--robot', 'none')
    with client(gw) as ros:
        cam = Camera(ros, '/camera/image_raw/compressed')
        try:
            wait_for(lambda: cam.count >= 2, 10)
            ctx, page, errors = open_teleop(chromium, gw)
            try:
                page.wait_for_function(
                    "document.querySelector('#camera').naturalWidth > 0"
                    " && /age \\d+ ms/.test(document.querySelector('#camera-info').textContent)", timeout=30000)
                size = page.evaluate("[document.querySelector('#camera').naturalWidth,"
                                     " document.querySelector('#camera').naturalHeight]")
                assert size == [320, 240]   # the camera sends 640x480; the page asked for 320 wide
                info = page.inner_text('#camera-info')
                assert 'jpeg' in info and '≤320 px' in info
                assert not errors
            finally:
                ctx.close()
        finally:
            cam.close()
