"""Run control in Chromium against the simulated turtlesim: a status error about any op of the
program ends the run on the block that sent it, and Step runs one whole block, then holds."""

from __future__ import annotations

import math
import subprocess
import sys
import time

from tests.support.ide import ARTIFACTS, bool_message, ex, program
from tests.support.ros import LOOP_HEADING, LOOP_REACH
from tests.support.wait import wait_for


def test_wrong_type_publish_fails_on_its_block(turtle_gateway, turtle_ros, ide_factory):
    ide = ide_factory(turtle_gateway)
    cmd = turtle_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
    publish = ex.block("ros_publish", {"TOPIC": "/turtle1/cmd_vel", "TYPE": "geometry_msgs/msg/Twist"},
                       {"MSG": bool_message()}, id="bad-publish")
    drive = ex.block("turtle_drive", inputs={"TURTLE": ex.text("turtle1"), "SPEED": ex.num(0.5),
                                             "TURN": ex.num(0), "SECONDS": ex.num(0.3)})
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(
        ex.log(ex.text("before")), drive, publish,
        ex.block("ros_sleep", inputs={"SECONDS": ex.num(60)}), ex.log(ex.text("after")))))
    ide.run()
    ide.wait_idle(timeout=20)      # the error ends the run long before the 60 s wait
    assert ide.logs() == ["before"]
    errors = ide.js("Object.fromEntries(rosgateIde.runner.errors)")
    assert list(errors) == ["bad-publish"], errors
    assert "data" in errors["bad-publish"] and "Twist" in errors["bad-publish"], errors
    assert "(id " not in errors["bad-publish"]
    warning = ide.js("rosgateIde.workspace.getBlockById('bad-publish')"
                     ".getIcon(Blockly.icons.IconType.WARNING)?.getText()")
    assert warning == errors["bad-publish"]
    text = ide.console_text()
    assert errors["bad-publish"] in text and "stopped after an error (robot stopped)" in text
    assert "finished" not in text
    # the robot was stopped: the last command on the velocity topic is zero
    wait_for(lambda: cmd.latest() == {"linear": {"x": 0.0, "y": 0.0, "z": 0.0},
                                      "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}, what="a zero command last")
    assert not ide.errors, ide.errors


def test_wrong_type_publish_ends_the_python_program(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    publish = ex.block("ros_publish", {"TOPIC": "/turtle1/cmd_vel", "TYPE": "geometry_msgs/msg/Twist"},
                       {"MSG": bool_message()})
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(
        ex.log(ex.text("before")), publish,
        ex.block("ros_sleep", inputs={"SECONDS": ex.num(60)}), ex.log(ex.text("after")))))
    path = ARTIFACTS / "wrong_type_publish.py"
    path.write_text(ide.python())
    proc = subprocess.run([sys.executable, str(path), "--url", turtle_gateway.ws_url],
                          capture_output=True, text=True, timeout=50)   # far less than the 60 s wait
    assert proc.returncode == 1, proc
    assert proc.stdout.splitlines() == ["before"]
    assert "unknown field 'data'" in proc.stderr and "(id " not in proc.stderr, proc.stderr


def test_publish_ids_name_their_block(turtle_gateway, ide_factory):
    """Every publish of a run carries an id the runtime maps back to the block that sent it."""
    ide = ide_factory(turtle_gateway)
    ide.js("""() => {
      window.sent = [];
      // every connection's sends, the one the page may open again after a stall included
      const proto = Object.getPrototypeOf(rosgateIde.ros);
      const send = proto.callOnConnection;
      proto.callOnConnection = function (m) { window.sent.push(m); return send.call(this, m); };
    }""")
    publish = ex.block("ros_publish", {"TOPIC": "/chatter_ids", "TYPE": "std_msgs/msg/String"},
                       {"MSG": {"type": "ros_message",
                                "extraState": {"kind": "msg", "type": "std_msgs/msg/String",
                                               "fields": [{"name": "data", "type": "string", "array": -1}]},
                                "fields": {"TYPE": "std_msgs/msg/String"},
                                "inputs": {"F_data": {"shadow": {"type": "text", "fields": {"TEXT": "hi"}}}}}},
                       id="good-publish")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(publish))
    ide.run()
    ide.wait_idle(timeout=15)
    ops = ide.js("window.sent.filter((m) => m.op === 'publish' && m.topic === '/chatter_ids')")
    assert len(ops) == 1 and ops[0]["id"].startswith("publish:/chatter_ids:rosgate"), ops
    assert "finished" in ide.console_text()
    assert not ide.js("rosgateIde.runner.errors.size")


def pose_xy(pose):
    m = pose.latest()
    return (m["x"], m["y"]) if m else None


def test_step_runs_one_whole_block_then_holds(turtle_gateway, turtle_ros, ide_factory):
    ide = ide_factory(turtle_gateway)
    turtle_ros.call("/reset", "std_srvs/srv/Empty")
    pose = turtle_ros.watch("/turtle1/pose", "turtlesim/msg/Pose")
    cmd = turtle_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
    ide.load_example("drive_square.json")
    ids = ide.js("""() => {
      const top = rosgateIde.workspace.getTopBlocks(true)[0];
      const rep = top.getNextBlock();
      const move = rep.getInputTargetBlock('DO');
      return {pen: top.id, repeat: rep.id, move: move.id, turn: move.getNextBlock().id};
    }""")
    wait_for(lambda: pose_xy(pose), what="a pose")

    def step_to(block_id: str):
        ide.page.click("#step")
        ide.page.wait_for_function("(id) => rosgateIde.runner.heldAt === id", arg=block_id, timeout=30000)
        assert ide.js("document.body.dataset.run") == "paused"

    start = pose_xy(pose)
    step_to(ids["move"])                 # the first Step runs the pen block; the loop itself is no step
    assert pose_xy(pose) == start
    assert "▷ step: " in ide.console_text()
    t0 = time.monotonic()
    step_to(ids["turn"])                 # the whole move: 3 m, then it holds with the robot stopped
    wait_for(lambda: (pose.latest() or {}).get("linear_velocity", 1) == 0, what="the turtle halted")
    end = pose_xy(pose)
    moved = math.hypot(end[0] - start[0], end[1] - start[1])
    assert abs(moved - 3) < LOOP_REACH, f"one Step moved the turtle {moved:.3f} m, not 3"
    assert any(m["linear"]["x"] == 0 and m["angular"]["z"] == 0 for t, m in cmd.since(t0))
    theta0 = pose.latest()["theta"]
    step_to(ids["move"])                 # the whole turn: 90 degrees, then the next round's move holds
    turned = (pose.latest()["theta"] - theta0 + math.pi) % (2 * math.pi) - math.pi
    assert abs(turned - math.pi / 2) < LOOP_HEADING, math.degrees(turned)
    assert math.hypot(pose_xy(pose)[0] - end[0], pose_xy(pose)[1] - end[1]) < 0.01
    ide.page.click("#stop")
    ide.wait_idle()
    assert not ide.errors, ide.errors


def test_step_runs_a_whole_block_while_a_handler_runs(turtle_gateway, turtle_ros, ide_factory):
    """A message handler that holds between its blocks does not make a stepped move hold midway."""
    ide = ide_factory(turtle_gateway)
    turtle_ros.call("/reset", "std_srvs/srv/Empty")
    pose = turtle_ros.watch("/turtle1/pose", "turtlesim/msg/Pose")
    handler = ex.block("ros_on_message", {"TOPIC": "/turtle1/pose", "TYPE": "turtlesim/msg/Pose",
                                          "VAR": {"id": "v-msg"}},
                       {"DO": {"type": "math_change", "fields": {"VAR": {"id": "v-n"}},
                               "inputs": {"DELTA": ex.num(1)}}})
    move = ex.block("turtle_move", inputs={"TURTLE": ex.text("turtle1"), "DIST": ex.num(2)}, id="move")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(
        handler, ex.seq(move, {**ex.log(ex.text("moved")), "id": "after"}),
        variables={"msg": "v-msg", "n": "v-n"}))
    start = wait_for(lambda: pose_xy(pose), what="a pose")
    ide.page.click("#step")                         # the first press: the whole move, the handler stepping too
    wait_for(lambda: math.hypot(pose_xy(pose)[0] - start[0], pose_xy(pose)[1] - start[1]) > 1.95,
             timeout=30, what="one Step moving the turtle the whole 2 m")
    wait_for(lambda: (pose.latest() or {}).get("linear_velocity", 1) == 0, what="the turtle halted")
    moved = math.hypot(pose_xy(pose)[0] - start[0], pose_xy(pose)[1] - start[1])
    assert abs(moved - 2) < LOOP_REACH, moved
    assert ide.logs() == [] and ide.js("document.body.dataset.run") == "paused"
    ide.page.click("#run")                          # Resume: every held part goes on
    ide.page.wait_for_function("rosgateIde.console.logs().includes('moved')", timeout=10000)
    ide.page.click("#stop")
    ide.wait_idle()
    assert not ide.errors, ide.errors
