"""A gamepad on the teleop page, in Chromium: a pad the test holds in its hands (navigator.getGamepads
answered by the page's own script, set before the page's; the events the browser sends), and the
Twists an independent roslibpy client sees on the rover's /cmd_vel. The stick drives only while the
dead-man button is held, within the speed slider; letting go, unplugging, a hidden tab each send the
zero a released joystick sends, and nothing after it."""

from __future__ import annotations

import time

from tests.support.wait import wait_for

# A standard-mapping pad the test moves: window.pad.set({axes, buttons}), .plug(bool); a hidden tab
# by window.hideTab(bool) (what the browser says of a tab sent to the background).
PAD = """
(() => {
  const pad = { id: 'Test pad (STANDARD GAMEPAD Vendor: 045e Product: 028e)', index: 0, connected: true,
    mapping: 'standard', timestamp: 0, axes: [0, 0, 0, 0],
    buttons: Array.from({ length: 17 }, () => ({ pressed: false, touched: false, value: 0 })) };
  let plugged = false;
  Object.defineProperty(Navigator.prototype, 'getGamepads', { configurable: true, value: () => (plugged ? [pad] : []) });
  const event = (type) => { const e = new Event(type); e.gamepad = pad; window.dispatchEvent(e); };
  window.pad = {
    set({ axes, deadman }) {
      if (axes) pad.axes = axes;
      if (deadman !== undefined) pad.buttons[4] = { pressed: deadman, touched: deadman, value: deadman ? 1 : 0 };
      pad.timestamp = performance.now();
    },
    plug(on) { plugged = on; pad.connected = on; event(on ? 'gamepadconnected' : 'gamepaddisconnected'); },
  };
  let hidden = false;
  Object.defineProperty(Document.prototype, 'hidden', { configurable: true, get: () => hidden });
  Object.defineProperty(Document.prototype, 'visibilityState', { configurable: true, get: () => (hidden ? 'hidden' : 'visible') });
  window.hideTab = (on) => { hidden = on; document.dispatchEvent(new Event('visibilitychange')); };
})();
"""
TWIST = "geometry_msgs/msg/Twist"


def moving(m) -> bool:
    return bool(m["linear"]["x"] or m["angular"]["z"])


def test_the_left_stick_drives_only_while_the_deadman_is_held(chromium, rover):
    gw, ros = rover
    cmd = ros.watch("/cmd_vel", TWIST)
    odom = ros.watch("/odom", "nav_msgs/msg/Odometry")
    ctx = chromium.new_context(viewport={"width": 1024, "height": 768})
    ctx.add_init_script(PAD)
    page = ctx.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    try:
        page.goto(gw.http_url + "teleop")
        page.wait_for_function("document.body?.dataset.ready === 'true' && document.body.dataset.connection === 'connected'")
        page.wait_for_function("document.querySelector('#topic').value === '/cmd_vel'")
        page.eval_on_selector("#maxspeed", "el => { el.value = '0.3'; el.dispatchEvent(new Event('input')); }")

        def ticks(n: int = 10) -> None:
            """n more odometry messages: time passing on the robot's clock, not the test's."""
            k = len(odom.messages)
            wait_for(lambda: len(odom.messages) >= k + n, what=f"{n} odometry messages")

        def zero_and_silence(since: float, what: str) -> None:
            zero = wait_for(lambda: next((t for t, m in cmd.since(since) if not moving(m)), None), timeout=5,
                            what=f"the zero on {what}")
            ticks()
            assert not [m for t, m in cmd.since(zero) if moving(m)], f"moving commands after {what}'s zero"

        # plugged in, its button held at plug-in: nothing until it has been let go once
        page.evaluate("pad.set({deadman: true, axes: [0, -1, 0, 0]}); pad.plug(true)")
        page.wait_for_function("!document.querySelector('#gamepad').hidden")
        t0 = time.monotonic()
        ticks()
        assert not cmd.since(t0), "a pad found held drove"
        # the stick alone: nothing
        page.evaluate("pad.set({deadman: false, axes: [0, -1, 0, 0]})")
        ticks()
        assert not [m for t, m in cmd.since(t0) if moving(m)]

        # held: forward at the slider's speed, then a left turn
        t1 = time.monotonic()
        page.evaluate("pad.set({deadman: true})")
        wait_for(lambda: len([m for t, m in cmd.since(t1) if m["linear"]["x"] > 0]) >= 3, timeout=10, what="driving forward")
        assert all(m["linear"]["x"] == 0.3 and m["angular"]["z"] == 0 for t, m in cmd.since(t1)), cmd.since(t1)
        t2 = time.monotonic()
        page.evaluate("pad.set({axes: [-1, 0, 0, 0]})")
        wait_for(lambda: [m for t, m in cmd.since(t2) if m["angular"]["z"] > 0 and m["linear"]["x"] == 0], timeout=10,
                 what="turning left")
        assert max(m["angular"]["z"] for t, m in cmd.since(t2)) <= 0.6 + 1e-9   # the slider's turn: twice its speed

        # let go of the button: the zero, and nothing after
        t3 = time.monotonic()
        page.evaluate("pad.set({deadman: false})")
        zero_and_silence(t3, "letting go")

        # unplugged while driving; plugged in again held, it waits for a new press
        page.evaluate("pad.set({deadman: true, axes: [0, -1, 0, 0]})")
        t4 = time.monotonic()
        wait_for(lambda: [m for t, m in cmd.since(t4) if moving(m)], timeout=10, what="driving again")
        t5 = time.monotonic()
        page.evaluate("pad.plug(false)")
        page.wait_for_function("document.querySelector('#gamepad').hidden")
        zero_and_silence(t5, "the unplug")
        t6 = time.monotonic()
        page.evaluate("pad.plug(true)")
        ticks()
        assert not [m for t, m in cmd.since(t6) if moving(m)], "the pad drove again without a new press"

        # a new press drives; the tab hidden stops it
        page.evaluate("pad.set({deadman: false}); new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)))")
        page.evaluate("pad.set({deadman: true})")
        t7 = time.monotonic()
        wait_for(lambda: [m for t, m in cmd.since(t7) if moving(m)], timeout=10, what="driving after a new press")
        t8 = time.monotonic()
        page.evaluate("hideTab(true)")
        zero_and_silence(t8, "the hidden tab")
        page.evaluate("hideTab(false)")
        t9 = time.monotonic()
        ticks()
        assert not [m for t, m in cmd.since(t9) if moving(m)], "the pad drove when the tab came back, still held"
        assert not errors, errors
    finally:
        ctx.close()
