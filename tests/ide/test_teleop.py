"""The teleop page on a tablet-sized touch screen, driving the simulated rover."""

from __future__ import annotations

import statistics
import time

from tests.support.ide import ARTIFACTS, PHONE, open_teleop
from tests.support.wait import wait_for


def drag(cdp, x0, y0, dx, dy, steps=8):
    cdp.send("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": [{"x": x0, "y": y0}]})
    for i in range(1, steps + 1):
        cdp.send("Input.dispatchTouchEvent", {"type": "touchMove", "touchPoints": [
            {"x": x0 + dx * i / steps, "y": y0 + dy * i / steps}]})


def release(cdp):
    cdp.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})


class Sent(list):
    """The ops a page sent, with a mark where a held drag began."""
    held = 0


LOOK = "JSON.stringify({lost: teleop.link?.lastLost ?? null, state: teleop.link?.state, blocked: teleop.blocked," \
       " notice: teleop.notice, joy: teleop.joy, published: teleop.published})"


def hold_stick(page, cdp, cmd, x0, y0, dx, dy, enough, ops: list | None = None) -> float:
    """Drags the stick by (dx, dy) and holds it until ``enough(commands since)`` is true. A link the page gave up meanwhile (a gateway starved on a busy machine)
    rightly stops the page, which drives again only on a fresh touch: that touch is made, once the
    page is connected again (twice at most); anything else failing says what the page saw. The
    time returned is the stick's arrival: what the page sends from its next tick is the full drag.
    ``ops`` (the page's sent ops, if gathered) gets the mark ``ops.held`` where the held drag began."""
    for attempt in range(3):
        lost = page.evaluate("JSON.stringify(teleop.link?.lastLost ?? null)")
        if ops is not None:
            ops.held = len(ops)
        drag(cdp, x0, y0, dx, dy)
        t0 = time.monotonic()
        try:
            wait_for(lambda: enough(cmd.since(t0))
                     or page.evaluate("JSON.stringify(teleop.link?.lastLost ?? null)") != lost,
                     timeout=30, what="commands from the held stick")
        except AssertionError as e:
            raise AssertionError(f"{e}; the page: {page.evaluate(LOOK)}") from None
        if enough(cmd.since(t0)):
            return t0
        release(cdp)
        page.wait_for_function("document.body?.dataset.connection === 'connected'")
    raise AssertionError(f"the link was lost under three drags; the page: {page.evaluate(LOOK)}")


def test_joystick_drives_at_10_hz_and_release_stops(chromium, rover):
    gw, ros = rover
    cmd = ros.watch("/cmd_vel", "geometry_msgs/msg/Twist")
    odom = ros.watch("/odom", "nav_msgs/msg/Odometry")
    ops = Sent()    # the page's publish ops, each stamped with the page's clock when it left (t, ms)
    ctx, page, errors = open_teleop(chromium, gw, sent=ops, viewport={"width": 1024, "height": 768},
                                    has_touch=True, is_mobile=True)
    try:
        page.wait_for_function("document.querySelector('#topic').value === '/cmd_vel'")
        cdp = ctx.new_cdp_session(page)
        box = page.locator("#joystick").bounding_box()
        cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2

        # forward: drag up
        for attempt in range(3):   # a link given up after the hold (see hold_stick): a fresh hold
            t0 = hold_stick(page, cdp, cmd, cx, cy, 0, -box["height"] / 2,
                            lambda got: len([m for t, m in got if m["linear"]["x"] > 0.3]) >= 16, ops)
            lost = page.evaluate("JSON.stringify(teleop.link?.lastLost ?? null)")
            page.screenshot(path=str(ARTIFACTS / "teleop-tablet-driving.png"))
            held = ops[ops.held:]
            t_release = time.monotonic()
            release(cdp)
            wait_for(lambda: any(m["linear"]["x"] == 0 and m["angular"]["z"] == 0 for t, m in cmd.since(t_release)),
                     timeout=1, what="zero on release")
            if page.evaluate("JSON.stringify(teleop.link?.lastLost ?? null)") == lost:
                break
            page.wait_for_function("document.body?.dataset.connection === 'connected'")
        assert all(m["linear"]["x"] >= 0 for t, m in cmd.since(t0) if t < t_release)   # never backwards
        # what the page sent while the stick was held (the robot also gets the gateway's zero when
        # a link the page gave up on a busy machine closes: the page's own ops say what it did)
        sent = [op["msg"] for op in held if op.get("op") == "publish" and op.get("topic") == "/cmd_vel"]
        first = next(i for i, m in enumerate(sent) if m["linear"]["x"] > 0.3)   # full deflection
        forward = sent[first:]
        look = page.evaluate(LOOK)
        assert all(m["linear"]["x"] > 0.3 for m in forward[1:]), (look, forward)
        assert all(abs(m["angular"]["z"]) < 0.05 for m in forward[1:]), (look, forward)
        max_speed = float(page.input_value("#maxspeed"))
        assert max(m["linear"]["x"] for m in forward) <= max_speed + 1e-9
        # the rate as the page sent it (its own stamps: arrivals bunch on a busy machine)
        stamps = [op["t"] for op in list(ops) if op.get("op") == "publish" and op.get("topic") == "/cmd_vel"
                  and op["msg"]["linear"]["x"] > 0.3]
        assert len(stamps) >= 16, stamps
        rate = 1000 / statistics.median(b - a for a, b in zip(stamps, stamps[1:]))
        assert 8 <= rate <= 12.5, f"{rate:.1f} Hz"

        # nothing but the zero after the release
        zero_at = next(t for t, m in cmd.since(t_release) if m["linear"]["x"] == 0)
        wait_for(lambda: len(odom.since(zero_at)) >= 5, what="five odometry messages after the release")
        assert len(cmd.since(zero_at)) == 1

        # left: drag left turns counter-clockwise (angular.z > 0); right the other way
        for dx, sign in ((-1, 1), (1, -1)):
            t1 = hold_stick(page, cdp, cmd, cx, cy, dx * box["width"] / 2, 0, lambda got: len(got) >= 4)
            turning = [m for t, m in cmd.since(t1)][2:]   # the first two may have left mid-drag
            release(cdp)
            assert all(m["angular"]["z"] * sign > 0.3 and abs(m["linear"]["x"]) < 0.05 for m in turning), turning
            wait_for(lambda: cmd.latest()["angular"]["z"] == 0, timeout=1, what="zero after the turn")
        assert not errors, errors
    finally:
        ctx.close()


def test_keys_slider_and_widgets(chromium, rover):
    gw, ros = rover
    cmd = ros.watch("/cmd_vel", "geometry_msgs/msg/Twist")
    ctx, page, errors = open_teleop(chromium, gw, viewport={"width": 1024, "height": 768}, has_touch=True)
    try:
        # battery gauge and camera view update from the rover
        page.wait_for_function("window.teleop.battery && /%/.test(document.querySelector('#battery-text').textContent)")
        page.wait_for_function("window.teleop.frames >= 2 && document.querySelector('#camera').naturalWidth > 0",
                               timeout=10000)
        pct = float(page.inner_text("#battery-text").split()[0])
        assert 0 <= pct <= 100
        # plots receive numbers
        page.wait_for_function("window.teleop && document.querySelectorAll('#plot canvas').length > 0")

        page.fill("#maxspeed", "0.2")
        page.dispatch_event("#maxspeed", "input")
        t0 = time.monotonic()
        page.keyboard.down("ArrowUp")
        wait_for(lambda: len(cmd.since(t0)) >= 3, what="commands while a key is held")
        page.keyboard.up("ArrowUp")
        wait_for(lambda: cmd.latest()["linear"]["x"] == 0, timeout=1, what="zero after the key is released")
        held = [m for t, m in cmd.since(t0)][:-1]
        assert all(abs(m["linear"]["x"] - 0.2) < 1e-9 for m in held), held

        t1 = time.monotonic()
        page.locator("#keys [data-key=right]").dispatch_event("pointerdown", {"pointerId": 1})
        wait_for(lambda: len(cmd.since(t1)) >= 2, what="commands from the on-screen key")
        page.locator("#keys [data-key=right]").dispatch_event("pointerup", {"pointerId": 1})
        wait_for(lambda: cmd.latest()["angular"]["z"] == 0, timeout=1, what="zero after the on-screen key")
        assert all(m["angular"]["z"] < 0 for t, m in cmd.since(t1)[:-1])
        page.screenshot(path=str(ARTIFACTS / "teleop-tablet.png"))
        page.set_viewport_size(PHONE)
        page.wait_for_function("document.querySelector('#drive').getBoundingClientRect().width < 400")
        page.screenshot(path=str(ARTIFACTS / "teleop-phone.png"), full_page=True)
        assert not errors, errors
    finally:
        ctx.close()
