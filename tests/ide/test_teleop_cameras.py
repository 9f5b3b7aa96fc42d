"""The teleop page shows every camera the robot has: the rover's own in the camera card, and two
more cameras (published here) side by side on a tablet, each unsubscribed when it is
unchecked in the picker (each made to measure by the ``image`` field of subscribe); a phone puts them one under the other."""

from __future__ import annotations

import pytest

from tests.support.camera import Camera
from tests.support.ros import client

from tests.support.ide import ARTIFACTS, PHONE, TABLET

WAIT = 60000
LOADED = "(sel) => [...document.querySelectorAll(sel)].filter((i) => i.complete && i.naturalWidth > 0).length"


@pytest.fixture(scope='module')
def cameras(start_gateway):
    gw = start_gateway('--robot', 'rover')
    with client(gw) as ros:
        front, back = Camera(ros, '/front/image_raw/compressed', 5), Camera(ros, '/back/image_raw/compressed', 5)
        try:
            yield gw
        finally:
            front.close()
            back.close()


@pytest.mark.parametrize('viewport', [TABLET, PHONE], ids=['tablet', 'phone'])
def test_every_camera_of_the_robot_is_shown(chromium, cameras, viewport):
    ctx = chromium.new_context(viewport=viewport)
    page = ctx.new_page()
    errors = []
    page.on('pageerror', lambda e: errors.append(str(e)))
    try:
        page.goto(cameras.http_url + 'teleop')
        page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=WAIT)
        page.wait_for_selector('#cameras-card:not([hidden])', timeout=WAIT)
        boxes = page.eval_on_selector_all('.camera-picker input', '(b) => b.map((x) => [x.value, x.checked])')
        assert boxes == [['/back/image_raw', True], ['/front/image_raw', True]], boxes   # not the main camera again
        page.wait_for_function(f"({LOADED})('.camera-grid img') === 2", timeout=WAIT)
        page.wait_for_function("teleop.frames > 0", timeout=WAIT)                      # the main camera too
        sizes = page.eval_on_selector_all('.camera-grid img', '(i) => i.map((x) => [x.naturalWidth, x.naturalHeight])')
        assert sizes == [[320, 240], [320, 240]], sizes          # made to measure, the aspect kept
        links = page.eval_on_selector_all('.camera-grid a', '(a) => a.map((x) => x.getAttribute("href"))')
        assert links == ['stream_viewer?topic=/back/image_raw', 'stream_viewer?topic=/front/image_raw'], links
        a, b = (page.locator('.camera-grid figure').nth(i).bounding_box() for i in (0, 1))
        if viewport is TABLET:
            assert abs(a['y'] - b['y']) < 2 and b['x'] > a['x'] + a['width'] - 1, (a, b)   # side by side
        else:
            assert b['y'] >= a['y'] + a['height'] - 1, (a, b)                             # one under the other
        page.locator('#cameras-card').scroll_into_view_if_needed()
        page.screenshot(path=str(ARTIFACTS / f'teleop-cameras-{"tablet" if viewport is TABLET else "phone"}.png'))

        page.uncheck('.camera-picker input[value="/back/image_raw"]')
        page.wait_for_function("document.querySelectorAll('.camera-grid img').length === 1", timeout=WAIT)
        page.reload()                                             # the choice is kept
        page.wait_for_function("document.querySelectorAll('.camera-picker input').length === 2", timeout=WAIT)
        assert not page.is_checked('.camera-picker input[value="/back/image_raw"]')
        page.check('.camera-picker input[value="/back/image_raw"]')
        page.wait_for_function(f"({LOADED})('.camera-grid img') === 2", timeout=WAIT)
        assert not errors, errors
    finally:
        ctx.close()
