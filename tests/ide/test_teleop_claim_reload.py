"""The teleop page on a fleet claims its station and reloads into it without publishing anything
on the root /cmd_vel first (on a robot without a fleet that topic is the real robot's)."""

from __future__ import annotations

import time

from tests.support.ide import open_teleop
from tests.support.ros import RosClient
from tests.support.wait import wait_for

TWIST = "geometry_msgs/msg/Twist"


def test_claim_and_reload_sends_nothing_to_the_root_cmd_vel(start_gateway, chromium):
    gw = start_gateway("--robot", "turtlesim", "--fleet", "2")
    ros = RosClient(gw)
    root = ros.watch("/cmd_vel", TWIST)
    ctx = None
    try:
        ctx, page, errors = open_teleop(chromium, gw)
        # the page reloads into its station: wait_for_function outlives the reload (and has a deadline)
        page.wait_for_function("(window.teleop?.robotNs?.get?.() || '').startsWith('/s0')"
                               " && document.body.dataset.connection === 'connected'", timeout=60000)
        ns = page.evaluate("teleop.robotNs.get()")
        station = ros.watch(f"{ns}/turtle1/cmd_vel", TWIST)
        page.wait_for_function("/turtle1\\/cmd_vel$/.test(document.querySelector('#topic').value)")
        page.focus("body")
        page.keyboard.press("Space")          # the page's Stop: a zero on its own topic only
        page.keyboard.down("ArrowUp")
        wait_for(lambda: station.messages, timeout=10, what="the page drives its station")
        page.keyboard.up("ArrowUp")
        time.sleep(0.5)   # what the page sent has had time to arrive (the station's did)
        assert root.messages == [], root.messages
        assert not errors
    finally:
        if ctx is not None:
            ctx.close()
        ros.close()
