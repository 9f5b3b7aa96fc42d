"""/twin in Chromium's software WebGL: a three.js robot drawn where the rover is, that turns on
the canvas when the rover turns; the world's walls, the laser scan, temperature colours and the
low-battery blink."""

from __future__ import annotations

import math
import time
from contextlib import contextmanager

import roslibpy

from tests.support.ide import ARTIFACTS, PHONE
from tests.support.ros import RosClient
from tests.support.wait import wait_for

PIXEL_POLL = 250   # ms between reads of the whole canvas (each is a full readPixels)
WAIT = 60000   # ms: a busy machine compiles the shaders slowly
# the rover's body colour (0xf08c1a, lit): red well above blue, green between
ORANGE = "(r, g, b) => r > 150 && b < 90 && g > 60 && g < 200 && r - b > 110"
PIXELS = """() => {
  const gl = twin.renderer.getContext();
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
  const px = new Uint8Array(w * h * 4);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
  const orange = (%s);
  const mask = [];
  for (let i = 0; i < w * h; i++) if (orange(px[4 * i], px[4 * i + 1], px[4 * i + 2])) mask.push(i);
  return { w, h, mask, webgl: gl instanceof WebGLRenderingContext || gl instanceof WebGL2RenderingContext };
}""" % ORANGE


@contextmanager
def phone_page(chromium, url: str):
    """(page, its errors) of a phone-sized page at url; closed after."""
    ctx = chromium.new_context(viewport=PHONE, has_touch=True)
    page = ctx.new_page()
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    try:
        page.goto(url)
        yield page, errors
    finally:
        ctx.close()


def turn(ros, angle: float = 1.0) -> None:
    """Turns the rover on the spot until its odometry says it turned by ``angle`` (rad), not for a
    time: a loaded machine may deliver the commands late, and the gateway zeroes the robot when
    this connection's publisher goes."""
    odom = ros.watch("/odom", "nav_msgs/msg/Odometry")
    yaw = lambda m: math.atan2(2 * m["pose"]["pose"]["orientation"]["w"] * m["pose"]["pose"]["orientation"]["z"],
                               1 - 2 * m["pose"]["pose"]["orientation"]["z"] ** 2)
    yaw0 = yaw(wait_for(odom.latest, what="odometry"))
    cmd = roslibpy.Topic(ros.ros, "/cmd_vel", "geometry_msgs/msg/Twist")
    cmd.advertise()
    turned = lambda: abs(math.remainder(yaw(odom.latest()) - yaw0, math.tau)) > angle
    deadline = time.monotonic() + 60
    while not turned():   # a command for each odometry message (25 Hz): the rover's own pace
        assert time.monotonic() < deadline, f"the rover did not turn by {angle} rad in 60 s: {odom.latest()}"
        cmd.publish(roslibpy.Message({"linear": {"x": 0, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 1.5}}))
        heard = len(odom.messages)
        wait_for(lambda: len(odom.messages) > heard, what="the next odometry message")
    cmd.unadvertise()


def test_twin_draws_the_rover_and_it_turns_on_the_canvas(chromium, rover):
    gw, ros = rover
    with phone_page(chromium, gw.http_url + "twin") as (page, errors):
        page.wait_for_function("document.body.dataset.ready === 'true' && !!window.twin", timeout=WAIT)
        page.wait_for_function("twin.state.model === 'urdf' && twin.state.pose !== null && twin.state.frames > 5", timeout=WAIT)
        page.wait_for_function("twin.state.markers >= 4 && twin.state.scanPoints > 100 && twin.state.battery > 0", timeout=WAIT)
        page.wait_for_function("Number.isFinite(twin.state.temps.left)", timeout=WAIT)
        page.wait_for_function(f"({PIXELS})().mask.length > 200", timeout=WAIT, polling=PIXEL_POLL)
        before = page.evaluate(PIXELS)
        yaw0 = page.evaluate("twin.robot.rotation.z")
        assert before["webgl"] and len(before["mask"]) > 200, len(before["mask"])   # the robot is on the canvas

        turn(ros)   # on the spot
        page.wait_for_function(f"Math.abs(twin.robot.rotation.z - ({yaw0})) > 0.6", timeout=WAIT)
        frames = page.evaluate("twin.state.frames")
        page.wait_for_function(f"twin.state.frames > {frames + 3}", timeout=WAIT)
        after = page.evaluate(PIXELS)
        a, b = set(before["mask"]), set(after["mask"])
        assert len(b) > 200
        assert len(a ^ b) > 0.3 * min(len(a), len(b)), (len(a), len(b), len(a ^ b))   # the drawn body turned
        page.screenshot(path=str(ARTIFACTS / "twin-phone.png"))

        # a wheel takes its motor's temperature colour (as the gauges: 50 amber, 65 red)
        colours = page.evaluate("""() => [30, 55, 70].map((t) => {
          twin.onTemperature('left', { temperature: t });
          return twin.model.wheels.left.material.color.getHex();
        })""")
        assert colours == [0x444a55, 0xffb300, 0xe53935]
        # a low battery blinks the body red (a fake report every 100 ms outvotes the rover's own)
        assert not page.evaluate("twin.state.lowBattery")
        page.evaluate("setInterval(() => twin.onBattery({ percentage: 0.1 }), 100)")
        page.wait_for_function("twin.state.blinkOn === true && twin.model.body.emissive.getHex() === 0xff0000", timeout=WAIT)
        page.wait_for_function("twin.state.blinkOn === false && twin.model.body.emissive.getHex() === 0", timeout=WAIT)
        page.wait_for_function("document.querySelector('#battery').dataset.level === 'danger'", timeout=WAIT)
        assert not errors, errors


def test_the_twin_connects_again_after_the_gateway_restarts_and_draws_on(chromium, start_gateway):
    """The gateway restarts at the same address: the twin's link makes the connection again by
    itself, subscribes again and draws the new gateway's rover as it turns, with the model it had
    (one robot in the scene). A twin that opened its connection once stayed closed."""
    gw = start_gateway("--robot", "rover")
    with phone_page(chromium, gw.http_url + "twin") as (page, errors):
        # the page's state is read once its entry module is there (tests/support/page_state.js)
        page.wait_for_function("document.body.dataset.ready === 'true' && !!window.twin", timeout=WAIT)
        page.wait_for_function("twin.state.model === 'urdf' && twin.state.pose !== null && twin.state.scanPoints > 100",
                               timeout=WAIT)
        robot = page.evaluate_handle("twin.robot")
        gw.stop()
        page.wait_for_function("document.body.dataset.connection !== 'connected'", timeout=WAIT)
        again = start_gateway("--robot", "rover", "--port", str(gw.port))
        page.wait_for_function("document.body.dataset.connection === 'connected'", timeout=WAIT)
        page.evaluate("twin.state.scanPoints = 0")
        yaw0 = page.evaluate("twin.robot.rotation.z")
        with RosClient(again) as ros:
            turn(ros)   # on the spot, on the new gateway
            try:
                page.wait_for_function(f"Math.abs(twin.robot.rotation.z - ({yaw0})) > 0.6", timeout=WAIT)
            except Exception as e:
                odom = ros.watch("/odom", "nav_msgs/msg/Odometry")
                wait_for(odom.latest, what="odometry")
                seen = page.evaluate("JSON.stringify({state: twin.state, yaw: twin.robot.rotation.z,"
                                     " lost: twin.link.lastLost, link: twin.link.state})")
                raise AssertionError(f"the twin did not turn: {seen}; the rover's odometry: {odom.latest()}") from e
        page.wait_for_function("twin.state.scanPoints > 100", timeout=WAIT)   # the scan subscribed again
        assert page.evaluate("(robot) => robot === twin.robot && twin.scene.children.filter((o) => o === robot).length", robot) == 1
        frames = page.evaluate("twin.state.frames")
        page.wait_for_function(f"twin.state.frames > {frames + 3}", timeout=WAIT)
        assert not errors, errors


def test_twin_of_a_fleet_station_and_the_teleop_link(chromium, start_gateway):
    gw = start_gateway("--fleet", "2", "--robot", "rover")
    with phone_page(chromium, gw.http_url + "teleop?ns=/s02") as (page, errors):
        page.wait_for_function("document.body?.dataset.ready === 'true' && !!window.teleop", timeout=WAIT)
        assert page.get_attribute("#twin-link", "href").endswith("twin?ns=%2Fs02")
        page.click("#twin-link")
        page.wait_for_function("window.twin && twin.state.model === 'urdf' && twin.state.pose !== null", timeout=WAIT)
        page.wait_for_function("twin.state.markers >= 4 && twin.state.scanPoints > 100", timeout=WAIT)
        assert page.input_value("#ns") == "/s02"
        page.wait_for_function(f"({PIXELS})().mask.length > 200", timeout=WAIT, polling=PIXEL_POLL)   # drawn once it is framed
        assert not errors, errors


def test_the_teleop_pages_3d_panel_draws_its_station_only_while_shown(chromium, start_gateway):
    gw = start_gateway("--fleet", "2", "--robot", "rover")
    with phone_page(chromium, gw.http_url + "teleop?ns=/s02") as (page, errors):
        page.wait_for_function("document.body?.dataset.ready === 'true' && !!window.teleop", timeout=WAIT)
        # hidden: no frame loaded, no WebGL, no second connection
        assert page.is_hidden("#twin-frame") and page.get_attribute("#twin-frame", "src") is None
        assert [f.url for f in page.frames if f != page.main_frame] in ([], ["about:blank"])
        page.click("#twin-show")
        assert page.get_attribute("#twin-show", "aria-expanded") == "true"
        page.wait_for_function("document.querySelector('#twin-frame').contentWindow.twin?.state.model === 'urdf'",
                               timeout=WAIT)
        twin = page.frame_locator("#twin-frame")
        frame = next(f for f in page.frames if f.url.endswith("twin?embed=1&ns=%2Fs02"))
        frame.wait_for_function("twin.state.pose !== null && twin.state.scanPoints > 100 && twin.state.frames > 5",
                                timeout=WAIT)
        frame.wait_for_function(f"({PIXELS})().mask.length > 200", timeout=WAIT, polling=PIXEL_POLL)   # s02's rover, drawn in the panel
        assert twin.locator("#battery").is_visible() and twin.locator("#ns").is_hidden()   # the page names the robot
        box = page.locator("#twin-frame").bounding_box()
        assert box["width"] > 300 and box["height"] > 200, box
        page.locator("#twin-card").scroll_into_view_if_needed()
        page.screenshot(path=str(ARTIFACTS / "teleop-3d-panel-phone.png"))
        page.click("#twin-show")                                   # hidden again: the frame is let go
        assert page.is_hidden("#twin-frame") and page.get_attribute("#twin-frame", "src") == "about:blank"
        page.wait_for_function("document.querySelector('#twin-frame').contentWindow.twin === undefined", timeout=WAIT)
        assert not errors, errors
