"""The teacher's view /class on a fleet, in Chromium: a live tile per station (world, who holds
it, running or idle, last error), stop-one, stop-all, release, the student's program read-only;
checked by the student's own IDE and by independent clients."""

from __future__ import annotations

import importlib.util
import json

import pytest

from tests.support.ide import ARTIFACTS, EXAMPLES, PHONE, TABLET
from tests.support.ros import RosClient
from tests.support.wait import wait_for

_spec = importlib.util.spec_from_file_location("make_examples", EXAMPLES / "make_examples.py")
ex = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ex)

TWIST = "geometry_msgs/msg/Twist"


def program(block: dict) -> dict:
    return {"format": "rosgate-program", "version": 1, "name": "long drive", "blocks": [],
            "workspace": {"blocks": {"languageVersion": 0, "blocks": [{**block, "x": 20, "y": 20}]}}}


def long_drive(seconds: float = 60) -> dict:
    return program(ex.block("turtle_drive", id="drive", inputs={
        "TURTLE": ex.text("turtle1"), "SPEED": ex.num(0.5), "TURN": ex.num(10), "SECONDS": ex.num(seconds)}))


def open_class(chromium, gw, viewport):
    ctx = chromium.new_context(viewport=viewport)
    page = ctx.new_page()
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: m.type == "error" and errors.append(m.text))
    page.goto(gw.http_url + "class")
    page.wait_for_function("document.body?.dataset.connection === 'connected'")
    return ctx, page, errors


def tile(page, ns: str) -> str:
    return f"article.tile[data-ns='{ns}']"


def tile_text(page, ns: str, part: str) -> str:
    return page.inner_text(f"{tile(page, ns)} .{part}")


@pytest.fixture(scope="module")
def fleet(start_gateway):
    return start_gateway("--robot", "turtlesim", "--fleet", "3", "--exclusive-control", "--cmd-timeout", "0")


def test_teacher_sees_stops_and_releases_stations(fleet, ide_factory, chromium):
    gw = fleet
    ctx, page, errors = open_class(chromium, gw, TABLET)
    ros = RosClient(gw)
    bob = None
    try:
        page.wait_for_function("document.body?.dataset.tiles === '3'")
        assert [page.get_attribute(t, "data-ns") for t in ("article.tile:nth-child(1)", "article.tile:nth-child(2)",
                                                             "article.tile:nth-child(3)")] == ["/s01", "/s02", "/s03"]
        # every tile draws its station's world
        page.wait_for_function("[...classView.tiles.values()].every((t) => (t.world.summary().robots || 0) === 1)")

        # a student opens the IDE: it claims /s01 by itself and takes its lease
        ide = ide_factory(gw, url=gw.http_url + "?name=Ada")
        ide.page.wait_for_function("rosgateIde.ns === '/s01' && rosgateIde.lease.state === 'you'")
        page.wait_for_function("document.querySelector(\"article.tile[data-ns='/s01'] .holder\").textContent === 'Ada drives'")
        assert tile_text(page, "/s02", "holder") == "free"

        # it runs a long drive: the tile says running; the teacher stops it
        cmd = ros.watch("/s01/turtle1/cmd_vel", TWIST)
        ide.js("(p) => rosgateIde.loadProgram(p)", long_drive())
        ide.run()
        wait_for(lambda: (cmd.latest() or {}).get("linear", {}).get("x") == 0.5, what="the program driving /s01")
        page.wait_for_function("document.querySelector(\"article.tile[data-ns='/s01']\").dataset.state === 'running'")
        assert "long drive" in tile_text(page, "/s01", "program")
        page.screenshot(path=str(ARTIFACTS / "class-tablet-running.png"))
        page.click(f"{tile(page, '/s01')} .stop")
        ide.wait_idle(timeout=10)                                  # the student's program stopped
        wait_for(lambda: cmd.latest()["linear"]["x"] == 0, what="zero velocity on /s01")
        assert ide.console_text().count("Stopped by the teacher") == 1
        page.wait_for_function("document.querySelector(\"article.tile[data-ns='/s01']\").dataset.state === 'idle'")
        page.wait_for_function("document.querySelector(\"article.tile[data-ns='/s01'] .holder\").textContent === \"Ada's station (stopped)\"")

        # the stop holds: another client cannot drive /s01, and Ada's Run says why in the console,
        # not as an error of her blocks
        import roslibpy
        bob = roslibpy.Ros(f"ws://{gw.host}:{gw.port}/?name=Bob")
        bob.run(timeout=10)
        roslibpy.Topic(bob, "/s01/turtle1/cmd_vel", TWIST).publish(roslibpy.Message({"linear": {"x": 0.1}}))
        ros.call("/rosapi/get_time", "rosapi/srv/GetTime")
        assert ide.js("rosgateIde.lease.holderOf('/s01')") is None
        ide.page.click("#run")
        ide.page.wait_for_function("/press Take to drive it again/.test(document.querySelector('#console-lines').textContent)")
        assert ide.js("rosgateIde.runner.errors.size") == 0 and ide.js("rosgateIde.runner.runs") == 1
        assert not page.evaluate("document.querySelector(\"article.tile[data-ns='/s01']\").hasAttribute('data-error')")

        # the student's program, read-only
        page.click(f"{tile(page, '/s01')} .open")
        page.wait_for_function("classView.programShown >= 1 && Blockly.getMainWorkspace().getBlockById('drive')")
        assert page.evaluate("Blockly.getMainWorkspace().options.readOnly") is True
        assert "Ada" in page.inner_text("#program-title")
        page.screenshot(path=str(ARTIFACTS / "class-program.png"))
        page.click("#program-close")

        # Release frees the station, and the student is told
        page.click(f"{tile(page, '/s01')} .release")
        page.wait_for_function("document.querySelector(\"article.tile[data-ns='/s01'] .holder\").textContent === 'free'")
        ide.page.wait_for_function("/teacher released \\/s01/.test(document.querySelector('#console-lines').textContent)")
        assert ide.js("rosgateIde.robotNs.mine") == ""

        # stop all: every station in use stopped (the gateway says when); a free one stays ready
        assert ros.call("/s02/fleet/claim", "std_srvs/srv/Trigger")["success"]
        page.wait_for_function("classView.owners['/s02']")
        page.click("#stop-all")
        page.wait_for_function("classView.lease.info.stopped['/s02']")
        ros.call("/rosapi/get_time", "rosapi/srv/GetTime")
        assert page.evaluate("['/s01', '/s03'].filter((ns) => classView.lease.info.halted[ns])") == []
        page.screenshot(path=str(ARTIFACTS / "class-tablet.png"))
        page.set_viewport_size(PHONE)
        page.wait_for_function("document.querySelector('article.tile').getBoundingClientRect().width < 390")
        assert page.evaluate("document.documentElement.scrollWidth") <= 390
        page.screenshot(path=str(ARTIFACTS / "class-phone.png"), full_page=True)
        assert not errors, errors
        assert not ide.errors, ide.errors
    finally:
        if bob is not None:
            bob.close()
        ros.close()
        ctx.close()


def test_class_is_for_admins(start_gateway, tmp_path, chromium):
    tokens = tmp_path / "tokens.toml"
    tokens.write_text('[[tokens]]\nname = "teacher"\nrole = "admin"\ntoken = "admin-token-123"\n\n'
                      '[[tokens]]\nname = "sam"\nrole = "operator"\ntoken = "operator-token-456"\n')
    gw = start_gateway("--robot", "turtlesim", "--fleet", "2", "--exclusive-control", "--auth", str(tokens))
    ctx = chromium.new_context(viewport=TABLET)
    try:
        page = ctx.new_page()
        page.goto(gw.http_url + "class")
        assert "/login" in page.url                                 # not signed in: sent to sign in
        page.fill("input[name=token]", "operator-token-456")
        page.click("button[type=submit]")
        assert "for admins" in page.inner_text("body")               # a student gets 403
        page.goto(gw.http_url + "login?next=/class")
        page.fill("input[name=token]", "admin-token-123")
        page.click("button[type=submit]")
        page.wait_for_url("**/class")
        page.wait_for_function("document.body?.dataset.tiles === '2'")
        page.wait_for_function("classView.lease.available")
        info = page.evaluate("classView.lease.info")
        assert info["stations"] == ["/s01", "/s02"]
        assert json.dumps(info["drivers"]) == '{"/s01": null, "/s02": null}'
    finally:
        ctx.close()


def test_without_the_lease_stop_publishes_zero(start_gateway, chromium):
    gw = start_gateway("--robot", "turtlesim", "--fleet", "2")
    ctx, page, errors = open_class(chromium, gw, PHONE)
    ros = RosClient(gw)
    try:
        page.wait_for_function("document.body?.dataset.tiles === '2'")     # from the fleet's parameter
        assert "--exclusive-control" in page.inner_text("#count")
        cmd = ros.watch("/s02/turtle1/cmd_vel", TWIST)
        wait_for(lambda: ros.call("/rosapi/subscribers", "rosapi/srv/Subscribers",
                                  {"topic": "/s02/turtle1/cmd_vel"})["subscribers"].count(gw.node),
                 what="the watcher subscribed")
        page.click(f"{tile(page, '/s02')} .stop")
        msg = wait_for(cmd.latest, what="a command on /s02")
        assert msg["linear"]["x"] == 0 and msg["angular"]["z"] == 0
        assert not errors, errors
    finally:
        ros.close()
        ctx.close()
