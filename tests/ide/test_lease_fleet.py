"""Who is driving (the driver lease of --exclusive-control) and fleet namespaces (--fleet), in
Chromium: the IDE and the teleop page against live gateways, checked by independent clients."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

from tests.support.ide import ARTIFACTS, EXAMPLES
from tests.support.ros import RosClient
from tests.support.wait import wait_for

_spec = importlib.util.spec_from_file_location("make_examples", EXAMPLES / "make_examples.py")
ex = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ex)

START = 5.544445
TWIST = "geometry_msgs/msg/Twist"


def program(block: dict) -> dict:
    return {"format": "rosgate-program", "version": 1, "name": "test program", "blocks": [],
            "workspace": {"blocks": {"languageVersion": 0, "blocks": [{**block, "x": 20, "y": 20}]}}}


def text_is(page, selector: str, text: str):
    page.wait_for_function("([s, t]) => document.querySelector(s).textContent.trim() === t", arg=[selector, text])


def test_who_is_driving(start_gateway, ide_factory, chromium):
    import roslibpy
    gw = start_gateway("--robot", "turtlesim", "--exclusive-control")
    ide = ide_factory(gw, url=gw.http_url + "?name=Ada")
    page = ide.page
    text_is(page, "#driver-name", "nobody")
    assert page.is_visible("#take") and not page.is_visible("#release")

    # Bob, another client, drives: the IDE names him and its own program is refused
    bob = roslibpy.Ros(f"ws://{gw.host}:{gw.port}/?name=Bob")
    bob.run(timeout=10)
    teleop = None
    try:
        roslibpy.Topic(bob, "/turtle1/cmd_vel", TWIST).publish(roslibpy.Message({"linear": {"x": 0.0}}))
        text_is(page, "#driver-name", "Bob")
        ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.block("turtle_drive", id="drive", inputs={
            "TURTLE": ex.text("turtle1"), "SPEED": ex.num(1), "TURN": ex.num(0), "SECONDS": ex.num(30)})))
        ide.run()
        ide.wait_idle(timeout=10)
        assert "Bob (client" in ide.js("rosgateIde.runner.errors.get('drive')")
        assert "is driving" in ide.console_text()
        ide.screenshot("ide-driver-refused")
        path = ARTIFACTS / "lease_drive.py"          # the same program in Python ends the same way
        path.write_text(ide.python())
        done = subprocess.run([sys.executable, str(path), "--url", gw.ws_url], capture_output=True, text=True,
                              timeout=60)
        assert done.returncode == 1 and "Bob (client" in done.stderr, done.stderr

        # the teleop page says so when its joystick or keys are refused
        ctx = chromium.new_context(viewport={"width": 1024, "height": 768})
        teleop = ctx.new_page()
        teleop.goto(gw.http_url + "teleop")
        teleop.wait_for_function("document.body?.dataset.connection === 'connected'")
        text_is(teleop, "#driver-name", "Bob")
        teleop.wait_for_function("document.querySelector('#topic').value === '/turtle1/cmd_vel'")
        teleop.keyboard.down("ArrowUp")
        teleop.wait_for_function("!document.querySelector('#notice').hidden")
        assert "Bob (client" in teleop.inner_text("#notice")
        teleop.screenshot(path=str(ARTIFACTS / "teleop-driver-refused.png"))
        teleop.keyboard.up("ArrowUp")

        # Take and Release
        page.click("#take")
        text_is(page, "#driver-name", "you")
        assert page.is_visible("#release") and not page.is_visible("#take")
        text_is(teleop, "#driver-name", "Ada")
        ide.screenshot("ide-driver-you")
        page.click("#release")
        text_is(page, "#driver-name", "nobody")
        teleop.wait_for_function("document.querySelector('#notice').hidden")
        assert not ide.errors, ide.errors
    finally:
        bob.close()
        if teleop is not None:
            teleop.context.close()


def test_no_lease_no_badge(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.page.wait_for_function("rosgateIde.graph.names('topic').includes('/turtle1/pose')")
    assert ide.page.is_hidden("#driver") and ide.page.is_hidden("#claim")


def test_fleet_claim_runs_the_program_on_the_claimed_robot(start_gateway, ide_factory):
    gw = start_gateway("--robot", "turtlesim", "--fleet", "2")
    ide = ide_factory(gw, url=gw.http_url + "?ns=/s02")
    page = ide.page
    assert ide.js("rosgateIde.world.topic") == "/s02/world/markers"
    page.wait_for_function("!document.querySelector('#claim').hidden && rosgateIde.robotNs.mine === '/s02'")
    page.click("#claim")                                  # this browser's station is /s02 already
    page.wait_for_function("rosgateIde.robotNs.mine === '/s02'")
    page.fill("#ns", "/s01")                              # another free one: /s02 is given back
    page.dispatch_event("#ns", "change")
    try:
        page.wait_for_function("rosgateIde.ns === '/s01' && rosgateIde.robotNs.mine === '/s01'")
    except Exception as e:   # what the page thought, for the next person
        raise AssertionError(f"{e}: {ide.js('({ns: rosgateIde.ns, mine: rosgateIde.robotNs.mine, lost: rosgateIde.robotNs.lost})')}"
                             f" {ide.console_text()}") from None
    assert page.input_value("#ns") == "/s01" and page.url.endswith("?ns=/s01")
    assert ide.js("rosgateIde.world.topic") == "/s01/world/markers"
    page.wait_for_function("(rosgateIde.world.summary().robots || 0) === 1")

    ros = RosClient(gw)     # watching after the claim: a watcher would put a station in use
    try:
        pose = {ns: ros.watch(f"{ns}/turtle1/pose", "turtlesim/msg/Pose") for ns in ("/s01", "/s02")}
        x = lambda ns: wait_for(pose[ns].latest, what=f"{ns} pose")["x"]  # noqa: E731
        assert abs(x("/s01") - START) < 1e-3 and abs(x("/s02") - START) < 1e-3

        ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.block("turtle_move", inputs={
            "TURTLE": ex.text("turtle1"), "DIST": ex.num(1)})))
        ide.run()
        ide.wait_idle(timeout=20)
        assert "finished" in ide.console_text()
        wait_for(lambda: abs(x("/s01") - (START + 1)) < 0.05, timeout=30, what="the /s01 turtle 1 m further")
        assert abs(x("/s02") - START) < 1e-3
        ide.screenshot("ide-fleet-claimed")

        # the same program in Python: the namespace chosen in the IDE by default, or --ns
        py = ide.python()
        assert "run(main, namespace='/s01')" in py and "rt.ns('/turtle1/cmd_vel')" in py
        path = ARTIFACTS / "fleet_move.py"
        path.write_text(py)
        for args, ns, goal in (([], "/s01", START + 2), (["--ns", "/s02"], "/s02", START + 1)):
            done = subprocess.run([sys.executable, str(path), "--url", gw.ws_url, *args],
                                  capture_output=True, text=True, timeout=60)
            assert done.returncode == 0, done.stderr
            wait_for(lambda: abs(x(ns) - goal) < 0.05, what=f"the {ns} turtle at x={goal:.2f}")
        assert abs(x("/s01") - (START + 2)) < 0.05   # the other station's turtle stayed put

        # the teleop page in the same browser drives the remembered robot
        teleop = page.context.new_page()
        teleop.goto(gw.http_url + "teleop")
        teleop.wait_for_function("document.querySelector('#topic').value === '/s01/turtle1/cmd_vel'")
        teleop.wait_for_function("!document.querySelector('#claim').hidden")
        assert teleop.input_value("#ns") == "/s01"
        teleop.screenshot(path=str(ARTIFACTS / "teleop-fleet.png"))
        assert not ide.errors, ide.errors
    finally:
        ros.close()
