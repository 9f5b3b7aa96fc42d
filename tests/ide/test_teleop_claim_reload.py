"""The teleop page on a fleet claims its station and reloads into it without publishing anything
on the root /cmd_vel first (on a robot without a fleet that topic is the real robot's)."""

from __future__ import annotations

from tests.support.ide import open_teleop, teleop_ready
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
        # the page reloads into its station: one look once it is there and not about to reload
        ns = teleop_ready(page, stations=r"^\/s0[12]$")
        station = ros.watch(f"{ns}/turtle1/cmd_vel", TWIST)
        page.wait_for_function("/turtle1\\/cmd_vel$/.test(document.querySelector('#topic').value)")
        page.focus("body")
        page.keyboard.press("Space")          # the page's Stop: a zero on its own topic only
        page.keyboard.down("ArrowUp")
        wait_for(lambda: any(m["linear"]["x"] > 0 for _, m in station.since(0)), timeout=30,
                 what="the page drives its station")
        page.keyboard.up("ArrowUp")
        # the zero after the key: whatever the page sent before it has come too (one connection, in order)
        wait_for(lambda: station.latest()["linear"]["x"] == 0, timeout=30, what="the zero after the key")
        assert root.messages == [], root.messages
        assert not errors
    finally:
        if ctx is not None:
            ctx.close()
        ros.close()
