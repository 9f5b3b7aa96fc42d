"""Teleop and the IDE on a fleet gateway (--fleet 3 --exclusive-control), in Chromium: a fresh
page claims a free station by itself and never drives one another client holds; its camera and
battery follow the station's namespace. Checked by independent clients on every station."""

from __future__ import annotations

import pytest

from tests.support.ide import ARTIFACTS, PHONE, TABLET, open_teleop
from tests.support.ros import RosClient
from tests.support.wait import wait_for

TWIST = "geometry_msgs/msg/Twist"


@pytest.fixture(scope="module")
def fleet(start_gateway):
    return start_gateway("--robot", "rover", "--fleet", "3", "--exclusive-control", "--cmd-timeout", "0")


def test_fresh_teleop_claims_a_free_station_and_spares_a_held_one(fleet, chromium, ide_factory):
    gw = fleet
    ros = RosClient(gw)
    import roslibpy
    zed = roslibpy.Ros(f"ws://{gw.host}:{gw.port}/?name=Zed")
    zed.run(timeout=10)
    contexts = []
    try:
        # Zed claims a station and drives it: /s01 is held
        claim = roslibpy.Service(zed, "/fleet/claim", "std_srvs/srv/Trigger").call(roslibpy.ServiceRequest({}), timeout=10)
        assert claim["success"] and claim["message"] == "/s01"
        roslibpy.Topic(zed, "/s01/cmd_vel", TWIST).publish(roslibpy.Message({"linear": {"x": 0.1}}))
        cmd = {"/s01": ros.watch("/s01/cmd_vel", TWIST)}   # a watcher puts a station in use: only held ones

        # a fresh teleop page (nothing remembered) claims the next free station and reloads under it
        ctx, page, errors = open_teleop(chromium, gw, viewport=TABLET, has_touch=True)
        contexts.append(ctx)
        page.wait_for_function("new URLSearchParams(location.search).get('ns') === '/s02'", timeout=15000)
        page.wait_for_function("document.body?.dataset.connection === 'connected' && document.querySelector('#topic').value === '/s02/cmd_vel'")
        assert page.input_value("#ns") == "/s02"
        assert page.input_value("#battery-topic") == "/s02/battery_state"
        assert page.input_value("#camera-topic") == "/s02/camera/image_raw/compressed"
        page.wait_for_function("window.teleop.battery && /%/.test(document.querySelector('#battery-text').textContent)")
        page.wait_for_function("window.teleop.frames >= 1", timeout=10000)
        page.wait_for_function("teleop.lease.state === 'you'")          # it holds its station
        cmd["/s02"] = ros.watch("/s02/cmd_vel", TWIST)
        before = {ns: len(w.messages) for ns, w in cmd.items()}
        page.keyboard.down("ArrowUp")
        wait_for(lambda: len(cmd["/s02"].messages) - before["/s02"] >= 3, what="commands on /s02")
        page.keyboard.up("ArrowUp")
        wait_for(lambda: cmd["/s02"].latest()["linear"]["x"] == 0, what="zero on /s02 after the key")
        page.screenshot(path=str(ARTIFACTS / "teleop-fleet-tablet.png"))

        # the teacher stops /s02 (no --auth: anyone may): the page says so, its keys stay refused
        # until its driver presses Take
        roslibpy.Topic(zed, "/rosgate/control", "std_msgs/msg/String").publish(roslibpy.Message({"data": "stop /s02"}))
        page.wait_for_function("/Stopped by the teacher/.test(document.querySelector('#notice').textContent)")
        n02 = len(cmd["/s02"].messages)
        page.keyboard.down("ArrowUp")
        page.wait_for_function("/stopped \\/s02; send \"take \\/s02\"/.test(document.querySelector('#notice').textContent)")
        page.keyboard.up("ArrowUp")
        ros.call("/rosapi/get_time", "rosapi/srv/GetTime")
        assert not any(m["linear"]["x"] for _, m in cmd["/s02"].messages[n02:]), "the stopped robot moved"
        page.click("#take")
        page.wait_for_function("teleop.lease.state === 'you'")
        n02 = len(cmd["/s02"].messages)
        page.keyboard.down("ArrowUp")
        wait_for(lambda: any(m["linear"]["x"] > 0 for _, m in cmd["/s02"].messages[n02:]), what="driving again after Take")
        page.keyboard.up("ArrowUp")
        page.set_viewport_size(PHONE)
        page.wait_for_function("document.querySelector('#drive').getBoundingClientRect().width < 390")
        page.screenshot(path=str(ARTIFACTS / "teleop-fleet-phone.png"), full_page=True)
        assert not errors, errors

        # a page pointed at Zed's station says who holds it and moves nothing there
        ctx2, held, errors2 = open_teleop(chromium, gw, "?ns=/s01", viewport=PHONE, has_touch=True)
        contexts.append(ctx2)
        # the lease's answer names the holder (a notice before it, such as the connection's, may come and go)
        held.wait_for_function("/Zed/.test(document.querySelector('#notice').textContent) && !document.querySelector('#notice').hidden")
        n01 = len(cmd["/s01"].messages)
        held.keyboard.down("ArrowUp")
        held.wait_for_function("/Zed \\(client \\d+\\) is driving \\/s01/.test(document.querySelector('#notice').textContent)")
        held.keyboard.up("ArrowUp")
        ros.call("/rosapi/get_time", "rosapi/srv/GetTime")                # a round trip after the attempts
        assert all(m["linear"]["x"] == 0.1 for m in [m for _, m in cmd["/s01"].messages][n01:]), "/s01 was driven"
        held.screenshot(path=str(ARTIFACTS / "teleop-fleet-held-phone.png"), full_page=True)
        assert not errors2, errors2

        # a fresh IDE claims the third station and takes its lease
        ide = ide_factory(gw, url=gw.http_url + "?name=Ivy")
        ide.page.wait_for_function("rosgateIde.ns === '/s03' && rosgateIde.lease.state === 'you'")
        assert ide.js("rosgateIde.world.topic") == "/s03/world/markers"
        ide.page.set_viewport_size(TABLET)
        ide.screenshot("ide-fleet-claimed-tablet")
        assert not ide.errors, ide.errors
    finally:
        zed.close()
        ros.close()
        for c in contexts:
            c.close()
