"""A class through a whole lesson, in Chromium: what a teacher found on a fleet with the driver
lease. A loose block never breaks Run or the Python; loading a program keeps its blocks; an error
about the program's last publish lands on its block; the generic ROS blocks' names are the page's
station's; Step says it steps; a recording says when it records nothing; the phone teleop shows
the camera with the joystick."""

from __future__ import annotations

import ast
import math
import subprocess
import sys

import pytest

from tests.support.ide import ARTIFACTS, PHONE, bool_message, ex, open_teleop, program
from tests.support.ros import RosClient
from tests.support.wait import wait_for

TWIST = "geometry_msgs/msg/Twist"
VECTOR3 = [{"name": n, "type": "float64", "array": -1} for n in "xyz"]


def vector3(x: float = 0) -> dict:
    return {"shadow": {"type": "ros_message", "extraState": {"kind": "msg", "type": "geometry_msgs/msg/Vector3",
                                                             "fields": VECTOR3},
                       "fields": {"TYPE": "geometry_msgs/msg/Vector3"},
                       "inputs": {"F_x": ex.num(x), "F_y": ex.num(0), "F_z": ex.num(0)}}}


def twist(x: float) -> dict:
    fields = [{"name": "linear", "type": "geometry_msgs/Vector3", "array": -1},
              {"name": "angular", "type": "geometry_msgs/Vector3", "array": -1}]
    return {"type": "ros_message", "extraState": {"kind": "msg", "type": TWIST, "fields": fields},
            "fields": {"TYPE": TWIST}, "inputs": {"F_linear": vector3(x), "F_angular": vector3()}}


def log(text: str, id: str | None = None) -> dict:
    return ex.block("ros_log", inputs={"VALUE": ex.text(text)}, id=id)


def run_python(ide, gw, name: str, *args: str) -> subprocess.CompletedProcess:
    path = ARTIFACTS / f"{name}.py"
    path.write_text(ide.python())
    return subprocess.run([sys.executable, str(path), "--url", gw.ws_url, *args],
                          capture_output=True, text=True, timeout=60)


# ---- loose blocks ---------------------------------------------------------------------------

def test_a_loose_block_breaks_neither_run_nor_the_python(turtle_gateway, turtle_ros, ide_factory):
    """A message block dropped into a publish block bumps its Twist out: that loose block (and a
    loose service call beside it) is greyed, marked and skipped by Run and by the .py file."""
    ide = ide_factory(turtle_gateway)
    cmd = turtle_ros.watch("/turtle1/cmd_vel", TWIST)
    pub = ex.block("ros_publish", {"TOPIC": "/turtle1/cmd_vel", "TYPE": TWIST}, {"MSG": twist(0.5)}, id="pub")
    call = ex.block("ros_call_service", {"SERVICE": "/no_such_service", "TYPE": "std_srvs/srv/Empty"}, id="call")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(log("before"), pub, log("after")), call))
    old = ide.js("rosgateIde.workspace.getBlockById('pub').getInputTargetBlock('MSG').id")
    # drop the toolbox's message block into the publish block: Blockly bumps the Twist out
    ide.js("""() => {
      const ws = rosgateIde.workspace;
      const m = Blockly.serialization.blocks.append({type: 'ros_message'}, ws);
      ws.getBlockById('pub').getInput('MSG').connection.connect(m.outputConnection);
    }""")
    assert ide.js("(old) => !rosgateIde.workspace.getBlockById(old).getParent()", old)
    js = ide.javascript()
    assert "{linear" not in js and "no_such_service" not in js, js
    assert "rt.publish('/turtle1/cmd_vel', 'geometry_msgs/msg/Twist', {});" in js, js

    ide.run()
    ide.wait_idle(timeout=15)
    text = ide.console_text()
    assert ide.logs() == ["before", "after"], text
    assert "2 loose blocks skipped" in text and "finished" in text, text
    assert not ide.js("rosgateIde.runner.errors.size"), text
    wait_for(lambda: cmd.latest() is not None, what="the publish of the program")
    ide.screenshot("lesson-loose-blocks")
    # both loose blocks are greyed and say why
    for block_id in (old, "call"):
        ide.page.wait_for_function("(id) => rosgateIde.workspace.getBlockById(id).getSvgRoot().classList.contains('rosgate-loose')",
                                   arg=block_id)
        warning = ide.js(f"rosgateIde.workspace.getBlockById('{block_id}').getIcon(Blockly.icons.IconType.WARNING)?.getText()")
        assert warning and "skips this block" in warning, (block_id, warning)

    python = ide.python()
    main = next(n for n in ast.parse(python).body if isinstance(n, ast.FunctionDef) and n.name == "main")
    assert not [n for n in main.body if isinstance(n, ast.Expr) and not isinstance(n.value, ast.Call)]
    assert "no_such_service" not in python
    proc = run_python(ide, turtle_gateway, "lesson_loose_blocks")
    assert proc.returncode == 0, proc
    assert proc.stdout.splitlines() == ["before", "after"], proc

    # plugged in again, a block is part of the program once more
    ide.js("""(old) => { const ws = rosgateIde.workspace;
      ws.getBlockById('pub').getInput('MSG').connection.connect(ws.getBlockById(old).outputConnection); }""", old)
    ide.page.wait_for_function("""(old) => !rosgateIde.workspace.getBlockById(old).getSvgRoot()
      .classList.contains('rosgate-loose')""", arg=old)
    assert "{linear: {x: 0.5, y: 0, z: 0}, angular: {x: 0, y: 0, z: 0}}" in ide.javascript()
    assert not ide.errors, ide.errors


def test_loading_a_program_keeps_its_message_blocks(turtle_gateway, ide_factory):
    """A saved publish block on a topic that is not the default keeps its saved message, even of
    another type than the topic's: no message block is swapped in and none is left loose."""
    ide = ide_factory(turtle_gateway)
    ide.page.wait_for_function("rosgateIde.graph.names('topic').includes('/turtle1/pose')")
    pub = ex.block("ros_publish", {"TOPIC": "/turtle1/pose", "TYPE": "turtlesim/msg/Pose"}, {"MSG": bool_message()},
                   id="pub")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(pub))
    # whatever the load set going (a type look-up, message details) has been answered by now
    ide.js("""async () => { await new Promise((r) => setTimeout(r, 0));
      await rosgateIde.graph.details('msg', 'turtlesim/msg/Pose');
      await rosgateIde.graph.call('/rosapi/get_time');
      await new Promise((r) => setTimeout(r, 0)); }""")
    blocks = ide.js("rosgateIde.workspace.getTopBlocks(false).map((b) => b.type)")
    assert blocks == ["ros_publish"], blocks
    assert ide.js("rosgateIde.workspace.getBlockById('pub').getInputTargetBlock('MSG').msgType") == "std_msgs/msg/Bool"
    assert not ide.errors, ide.errors


# ---- the last block's error and Step ---------------------------------------------------------

def test_an_error_in_the_last_block_is_reported_on_it(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    publish = ex.block("ros_publish", {"TOPIC": "/turtle1/cmd_vel", "TYPE": TWIST}, {"MSG": bool_message()},
                       id="last-publish")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(log("before"), publish)))
    ide.run()
    ide.wait_idle(timeout=15)
    text = ide.console_text()
    errors = ide.js("Object.fromEntries(rosgateIde.runner.errors)")
    assert list(errors) == ["last-publish"], text
    assert "unknown field 'data'" in errors["last-publish"], errors
    assert "stopped after an error" in text and "finished" not in text, text
    assert ide.page.locator("#console-lines .line.error[data-block='last-publish']").count() == 1

    proc = run_python(ide, turtle_gateway, "lesson_last_publish")
    assert proc.returncode == 1, proc
    assert proc.stdout.splitlines() == ["before"]
    assert "unknown field 'data'" in proc.stderr, proc.stderr

    # a program whose last publish is fine still just finishes
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(
        log("before"), ex.block("ros_publish", {"TOPIC": "/turtle1/cmd_vel", "TYPE": TWIST}, {"MSG": twist(0)}))))
    ide.run()
    ide.wait_idle(timeout=15)
    assert "■ run 2 finished" in ide.console_text()
    assert not ide.js("rosgateIde.runner.errors.size")
    assert not ide.errors, ide.errors


def test_step_says_it_is_stepping(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(log("a", "A"), log("b", "B"))))
    ide.page.click("#step")                 # the first press runs the first block, then holds
    ide.page.wait_for_function("rosgateIde.runner.heldAt === 'B'")
    lines = ide.page.locator("#console-lines .line.info").all_inner_texts()
    assert any("step by step" in line for line in lines), lines
    assert not any(line.startswith("▶ run") for line in lines), lines
    assert ide.js("document.body.dataset.run") == "paused"
    assert ide.logs() == ["a"]
    ide.page.locator("#console-lines .line.info", has_text="step: log").first.wait_for()
    ide.page.click("#step")
    ide.wait_idle(timeout=10)
    assert ide.logs() == ["a", "b"]
    assert not ide.errors, ide.errors


# ---- a fleet with the driver lease ----------------------------------------------------------

@pytest.fixture(scope="module")
def fleet(start_gateway, tmp_path_factory):
    return start_gateway("--robot", "turtlesim", "--robot", "rover", "--fleet", "3", "--exclusive-control",
                         "--record", str(tmp_path_factory.mktemp("recordings")), "--record-topics", "/nothing")


@pytest.fixture
def fleet_ros(fleet):
    with RosClient(fleet) as client:
        yield client


def claimed_ide(ide_factory, gw, **ctx):
    """An IDE page that claimed a station and drives it (its driver lease)."""
    ide = ide_factory(gw, **ctx)
    ide.page.wait_for_function("/^\\/s0\\d$/.test(rosgateIde.ns) && rosgateIde.lease.state === 'you'", timeout=15000)
    ide.page.wait_for_function("(ns) => rosgateIde.graph.names('topic').includes(ns + '/turtle1/pose')",
                               arg=ide.js("rosgateIde.ns"))
    return ide, ide.js("rosgateIde.ns")


def test_a_default_topic_publish_moves_the_pages_own_turtle(fleet, fleet_ros, ide_factory):
    ide, ns = claimed_ide(ide_factory, fleet)
    other = next(s for s in ("/s01", "/s02", "/s03") if s != ns)
    pose = fleet_ros.watch(f"{ns}/turtle1/pose", "turtlesim/msg/Pose")
    other_pose = fleet_ros.watch(f"{other}/turtle1/pose", "turtlesim/msg/Pose")
    start = wait_for(pose.latest, what="the station's turtle pose")
    other_start = wait_for(other_pose.latest, what="another station's turtle pose")
    # the publish block as it comes out of the toolbox: its default topic /turtle1/cmd_vel
    pub = ex.block("ros_publish", inputs={"MSG": twist(2)}, id="pub")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(pub, ex.block("ros_sleep", inputs={"SECONDS": ex.num(0.5)}))))
    assert ide.js("rosgateIde.workspace.getBlockById('pub').getFieldValue('TOPIC')") == "/turtle1/cmd_vel"
    ide.run()
    ide.wait_idle(timeout=15)
    assert "finished" in ide.console_text() and not ide.js("rosgateIde.runner.errors.size"), ide.console_text()
    moved = wait_for(lambda: math.hypot(pose.latest()["x"] - start["x"], pose.latest()["y"] - start["y"]) > 0.5,
                     what=f"the turtle of {ns} moving")
    assert moved
    assert (other_pose.latest()["x"], other_pose.latest()["y"]) == (other_start["x"], other_start["y"])
    # the code says where: in the robot namespace, which the .py file carries as its default
    assert "rt.publish(rt.ns('/turtle1/cmd_vel'), 'geometry_msgs/msg/Twist'" in ide.javascript()
    python = ide.python()
    assert "rt.publish(rt.ns('/turtle1/cmd_vel'), 'geometry_msgs/msg/Twist'" in python
    assert f"run(main, namespace='{ns}')" in python
    # names the gateway has as they are stay so; relative names are the station's
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(
        ex.block("ros_call_service_stmt", {"SERVICE": "/add_two_ints", "TYPE": "example_interfaces/srv/AddTwoInts"}),
        ex.block("ros_wait_message", {"TOPIC": "turtle1/pose", "TYPE": "turtlesim/msg/Pose"}),
        ex.block("ros_wait_message", {"TOPIC": f"{other}/turtle1/pose", "TYPE": "turtlesim/msg/Pose"}))))
    js = ide.javascript()
    assert "rt.callService('/add_two_ints'" in js
    assert "rt.waitForMessage(rt.ns('turtle1/pose')" in js
    assert f"rt.waitForMessage('{other}/turtle1/pose'" in js

    # the topic menu lists the station's own names first
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.block("ros_publish", id="pub")))
    ide.js("rosgateIde.workspace.getBlockById('pub').getField('TOPIC').showEditor()")
    items = ide.page.locator(".blocklyDropDownDiv .blocklyMenuItem")
    items.first.wait_for(state="visible")
    names = [t.strip() for t in items.all_inner_texts()]
    own = ["/turtle1/cmd_vel", "/turtle1/pose", "/cmd_vel", "/odom"]
    assert all(n in names for n in own), names
    last_own = max(names.index(n) for n in own)
    assert all(names.index(n) > last_own for n in names if n.startswith(("/s01/", "/s02/", "/s03/"))), names
    assert not any(n.startswith(f"{ns}/") for n in names), names
    ide.page.keyboard.press("Escape")
    assert not ide.errors, ide.errors


def test_recording_names_the_stations_topics_and_warns_when_nothing_matches(fleet, ide_factory):
    ide, ns = claimed_ide(ide_factory, fleet)
    page = ide.page
    page.evaluate("rosgateRecorder.topics.value = '/turtle1/pose'")
    page.click("#rec")
    page.wait_for_function("document.body?.dataset.recording === 'on'", timeout=15000)
    rec = page.evaluate("fetch('api/recordings').then((r) => r.json())")["recordings"]
    mine = [r for r in rec if r["state"] == "recording" and r["max_seconds"]]
    assert mine and mine[-1]["topics"] == [f"{ns}/turtle1/pose"], mine
    assert not page.is_visible("#dlg-recordings")
    page.click("#rec")
    page.wait_for_function("document.body?.dataset.recording === 'off'", timeout=10000)

    page.evaluate("rosgateRecorder.topics.value = '/no/such/topic'")
    page.click("#rec")
    page.wait_for_selector("#dlg-recordings[open]")
    assert "No topic matches" in page.inner_text("#dlg-recordings .rec-msg")
    page.wait_for_function("document.querySelector('#rec').textContent.includes('no topics')")
    page.click("#dlg-recordings button:text('Close')")
    page.click("#rec")
    page.wait_for_function("document.body?.dataset.recording === 'off'", timeout=10000)
    page.click("#recordings")
    page.wait_for_function("/0 messages/.test(document.querySelector('#dlg-recordings .rec-msg').textContent)")
    assert page.is_visible("#dlg-recordings .rec-msg.error")
    assert not ide.errors, ide.errors


def test_the_phone_teleop_shows_the_camera_with_the_joystick(fleet, chromium):
    ctx, page, errors = open_teleop(chromium, fleet, viewport=PHONE, has_touch=True, is_mobile=True)
    try:
        page.wait_for_function("new URLSearchParams(location.search).get('ns')", timeout=15000)
        page.wait_for_function("document.body?.dataset.connection === 'connected' && window.teleop.frames >= 1",
                               timeout=15000)
        page.wait_for_function("document.querySelector('#camera').naturalWidth > 0")
        boxes = page.evaluate("""() => Object.fromEntries(['#camera', '#joystick'].map((s) => {
          const r = document.querySelector(s).getBoundingClientRect();
          return [s, {top: r.top, bottom: r.bottom, left: r.left, right: r.right, height: r.height}];
        }))""")
        view = page.evaluate("({width: innerWidth, height: innerHeight})")
        page.screenshot(path=str(ARTIFACTS / "lesson-teleop-phone.png"))
        for name, box in boxes.items():
            assert box["height"] > 150, (name, box)
            assert 0 <= box["top"] and box["bottom"] <= view["height"], (name, box, view)
            assert 0 <= box["left"] and box["right"] <= view["width"], (name, box, view)
        assert boxes["#camera"]["bottom"] <= boxes["#joystick"]["top"], boxes
        assert not errors, errors
    finally:
        ctx.close()
