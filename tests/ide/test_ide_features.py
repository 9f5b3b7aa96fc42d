"""IDE behaviour in Chromium against a live gateway with the simulated turtlesim:
Stop, errors on blocks, live dropdowns, message literals, saving, sharing, the library, make-a-block."""

from __future__ import annotations

import json
import time
from pathlib import Path

from tests.support.ide import drive, ex, moving, program
from tests.support.wait import wait_for


def test_stop_publishes_zero_and_nothing_after(turtle_gateway, turtle_ros, ide_factory):
    """How soon the zero comes is a figure of `python -m tests.bench stop`; here, that it comes and
    is the last command."""
    ide = ide_factory(turtle_gateway)
    cmd = turtle_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
    pose = turtle_ros.watch("/turtle1/pose", "turtlesim/msg/Pose")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(drive()))
    ide.run()
    wait_for(lambda: moving(cmd), what="cmd_vel from the running program")
    wait_for(lambda: (pose.latest() or {}).get("linear_velocity", 0) > 0.5, what="the turtle moving")
    t0 = time.monotonic()
    ide.page.click("#stop")
    stopped = wait_for(lambda: next((t for t, m in cmd.since(t0)
                                     if m["linear"]["x"] == 0 and m["angular"]["z"] == 0), None),
                       what="zero cmd_vel after Stop")
    assert ide.js("document.body.dataset.run") == "idle"
    wait_for(lambda: (pose.latest() or {}).get("linear_velocity", 1) == 0, what="turtle halted")
    last_nonzero = max((t for t, m in cmd.messages if m["linear"]["x"] != 0), default=0)
    assert last_nonzero < stopped
    assert not ide.errors, ide.errors


def test_closing_the_tab_stops_the_robot(turtle_gateway, turtle_ros, ide_factory):
    ide = ide_factory(turtle_gateway)
    cmd = turtle_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(drive()))
    ide.run()
    wait_for(lambda: moving(cmd), what="cmd_vel from the running program")
    t0 = time.monotonic()
    ide.page.close(run_before_unload=True)
    wait_for(lambda: any(m["linear"]["x"] == 0 for t, m in cmd.since(t0)), timeout=2,
             what="zero cmd_vel after the tab closed")


def test_runtime_error_shows_on_its_block(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    call = ex.block("ros_call_service_stmt", {"SERVICE": "/no_such_service", "TYPE": "std_srvs/srv/Empty"}, id="bad-call")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(
        ex.log(ex.text("before")), call, ex.log(ex.text("after")))))
    ide.run()
    ide.wait_idle(timeout=15)
    assert ide.logs() == ["before"]
    errors = ide.js("Object.fromEntries(rosgateIde.runner.errors)")
    assert list(errors) == ["bad-call"]
    assert "/no_such_service" in errors["bad-call"]
    warning = ide.js("rosgateIde.workspace.getBlockById('bad-call').getIcon(Blockly.icons.IconType.WARNING)?.getText()")
    assert warning and "/no_such_service" in warning
    assert ide.page.locator("#console-lines .line.error[data-block='bad-call']").count() == 1
    ide.screenshot("ide-error-on-block")
    # clicking "show block" selects it
    ide.page.click("#console-lines .line.error .goto")
    assert ide.js("Blockly.getSelected()?.id") == "bad-call"


def open_dropdown(ide, block_id: str, field: str) -> list[str]:
    ide.js(f"rosgateIde.workspace.getBlockById('{block_id}').getField('{field}').showEditor()")
    items = ide.page.locator(".blocklyDropDownDiv .blocklyMenuItem")
    items.first.wait_for(state="visible")
    return [t.strip() for t in items.all_inner_texts()]


def pick(ide, text: str):
    ide.page.locator(".blocklyDropDownDiv .blocklyMenuItem", has_text=text).first.click()


def message_fields(ide, parent_id: str, input_name: str):
    return ide.js(f"""(() => {{
        const b = rosgateIde.workspace.getBlockById('{parent_id}').getInputTargetBlock('{input_name}');
        return b && {{type: b.msgType, kind: b.msgKind, fields: b.msgFields.map(f => f.name),
                     inputs: b.inputList.filter(i => i.name.startsWith('F_')).map(i => i.name)}};
    }})()""")


def test_dropdowns_list_the_live_graph_and_fill_types(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.js("(p) => rosgateIde.loadProgram(p)", program(
        ex.block("ros_publish", {"TOPIC": "/x", "TYPE": ""}, id="pub"),
        ex.block("ros_call_service_stmt", {"SERVICE": "/x", "TYPE": ""}, id="call"),
        ex.block("ros_send_goal", {"ACTION": "/x", "TYPE": ""}, id="goal"),
    ))
    ide.page.wait_for_function("rosgateIde.graph.names('topic').includes('/turtle1/pose')")
    topics = open_dropdown(ide, "pub", "TOPIC")
    for t in ("/turtle1/cmd_vel", "/turtle1/pose", "/world/markers"):
        assert t in topics, topics
    assert any("type a name" in t for t in topics)
    pick(ide, "/turtle1/cmd_vel")
    ide.page.wait_for_function("rosgateIde.workspace.getBlockById('pub').getFieldValue('TYPE') === 'geometry_msgs/msg/Twist'")
    ide.page.wait_for_function("rosgateIde.workspace.getBlockById('pub').getInputTargetBlock('MSG')")
    msg = message_fields(ide, "pub", "MSG")
    assert msg["type"] == "geometry_msgs/msg/Twist" and msg["fields"] == ["linear", "angular"]
    js = ide.javascript()
    assert ("rt.publish('/turtle1/cmd_vel', 'geometry_msgs/msg/Twist', "
            "{linear: {x: 0, y: 0, z: 0}, angular: {x: 0, y: 0, z: 0}});") in js

    services = open_dropdown(ide, "call", "SERVICE")
    for s in ("/spawn", "/turtle1/set_pen", "/add_two_ints", "/rosapi/topics"):
        assert s in services, services
    pick(ide, "/spawn")
    ide.page.wait_for_function("rosgateIde.workspace.getBlockById('call').getInputTargetBlock('REQUEST')")
    req = message_fields(ide, "call", "REQUEST")
    assert req == {"type": "turtlesim/srv/Spawn", "kind": "request", "fields": ["x", "y", "theta", "name"],
                   "inputs": ["F_x", "F_y", "F_theta", "F_name"]}
    assert ide.js("rosgateIde.workspace.getBlockById('call').getFieldValue('TYPE')") == "turtlesim/srv/Spawn"

    actions = open_dropdown(ide, "goal", "ACTION")
    assert "/fibonacci" in actions and "/turtle1/rotate_absolute" in actions, actions
    pick(ide, "/turtle1/rotate_absolute")
    ide.page.wait_for_function("rosgateIde.workspace.getBlockById('goal').getInputTargetBlock('GOAL')")
    goal = message_fields(ide, "goal", "GOAL")
    assert goal["type"] == "turtlesim/action/RotateAbsolute" and goal["fields"] == ["theta"]
    ide.screenshot("ide-dropdowns")
    assert not ide.errors, ide.errors


def test_message_literal_has_the_fields_of_its_type(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.js("(p) => rosgateIde.loadProgram(p)", program(
        ex.block("ros_log", inputs={"VALUE": ex.block("ros_message", {"TYPE": ""}, id="m",
                                                       extraState={"kind": "msg", "type": "", "fields": []})})))
    ide.page.wait_for_function("rosgateIde.graph.messageTypes().includes('turtlesim/msg/Pose')")
    types = open_dropdown(ide, "m", "TYPE")
    assert "turtlesim/msg/Pose" in types and "geometry_msgs/msg/Twist" in types, types
    pick(ide, "turtlesim/msg/Pose")
    ide.page.wait_for_function("rosgateIde.workspace.getBlockById('m').msgFields.length === 5")
    assert ide.js("rosgateIde.workspace.getBlockById('m').msgFields.map(f => f.name + ':' + f.type)") == [
        "x:float32", "y:float32", "theta:float32", "linear_velocity:float32", "angular_velocity:float32"]
    assert "rt.log({x: 0, y: 0, theta: 0, linear_velocity: 0, angular_velocity: 0});" in ide.javascript()
    assert "rt.log({'x': 0, 'y': 0, 'theta': 0, 'linear_velocity': 0, 'angular_velocity': 0})" in ide.python()
    # a nested type: every level gets its own message block
    ide.js("rosgateIde.workspace.getBlockById('m').getField('TYPE').setValue('geometry_msgs/msg/PoseStamped')")
    ide.page.wait_for_function("rosgateIde.workspace.getBlockById('m').msgFields.map(f => f.name).join() === 'header,pose'")
    js = ide.javascript()
    assert ("{header: {stamp: {sec: 0, nanosec: 0}, frame_id: ''}, pose: {position: {x: 0, y: 0, z: 0}, "
            "orientation: {x: 0, y: 0, z: 0, w: 0}}}") in js


def test_save_reload_and_share_link(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.load_example("spiral.json")
    ide.js("rosgateIde.workspace.getAllBlocks(false).find(b => b.type === 'math_number').setFieldValue(7, 'NUM')")
    saved = ide.js("rosgateIde.saved || 0")
    ide.page.wait_for_function(f"(rosgateIde.saved || 0) > {saved}")
    before = ide.workspace()
    ide.page.reload()
    ide.page.wait_for_function("document.body?.dataset.ready === 'true'")
    assert ide.workspace() == before
    assert ide.page.input_value("#name") == "spiral with the pen"

    ide.page.click("#share")
    link = ide.page.wait_for_function("rosgateIde.lastShareLink").json_value()
    assert "#program=" in link
    other = ide_factory(turtle_gateway, url=link)       # a fresh browser profile: no autosave there
    assert other.workspace() == before
    assert other.page.input_value("#name") == "spiral with the pen"
    # the IDE asks nothing of any host but the gateway
    origin = turtle_gateway.http_url.rstrip("/")
    assert any(u.endswith("/vendor/roslib.mjs") for u in ide.requests)
    foreign = [u for u in ide.requests + other.requests if not (u.startswith(origin) or u.startswith("data:") or u.startswith("blob:"))]
    assert not foreign, foreign


def test_program_library_and_files(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.page.on("dialog", lambda d: d.accept())
    ide.load_example("drive_square.json")
    before = ide.workspace()
    ide.page.fill("#name", "library square")
    ide.page.dispatch_event("#name", "change")
    ide.page.click("#library")
    ide.page.click("#library-save")
    ide.page.locator("#library-list .lib-open", has_text="library square").wait_for()
    stored = json.loads((Path(turtle_gateway.programs_dir) / "library square.json").read_text())
    assert stored["name"] == "library square" and stored["workspace"] == before
    ide.page.click("#library-close")

    ide.page.click("#new")
    assert ide.js("rosgateIde.workspace.getAllBlocks(false).length") == 0
    ide.page.click("#library")
    ide.page.locator("#library-list .lib-open", has_text="library square").click()
    ide.page.wait_for_function("rosgateIde.workspace.getAllBlocks(false).length > 0")
    assert ide.workspace() == before

    with ide.page.expect_download() as dl:
        ide.page.click("#download")
    saved = json.loads(Path(dl.value.path()).read_text())
    assert saved["workspace"] == before and saved["format"] == "rosgate-program"
    with ide.page.expect_download() as dl:
        ide.page.click("#download-py")
    assert dl.value.suggested_filename.endswith(".py")
    assert "rt.move(" in Path(dl.value.path()).read_text()

    ide.page.click("#new")
    with ide.page.expect_file_chooser() as fc:
        ide.page.click("#upload")
    fc.value.set_files(dl_path := str(Path(turtle_gateway.programs_dir) / "library square.json"))
    ide.page.wait_for_function("rosgateIde.workspace.getAllBlocks(false).length > 0")
    assert ide.workspace() == before, dl_path


def test_make_a_block_from_a_live_service(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.make_block("service", "/add_two_ints", "add", "my_service_add_two_ints")
    ide.js("(p) => rosgateIde.loadProgram(p)", {
        **program(ex.log(ex.block("my_service_add_two_ints", inputs={"F0": ex.num(2), "F1": ex.num(40)}))),
        "blocks": ide.js("rosgateIde.custom"),
    })
    assert ("await rt.callService('/add_two_ints', 'example_interfaces/srv/AddTwoInts', {a: 2, b: 40})"
            in ide.javascript())
    assert ("rt.call_service('/add_two_ints', 'example_interfaces/srv/AddTwoInts', {'a': 2, 'b': 40}), 'sum')"
            in ide.python())
    ide.run()
    ide.wait_idle(timeout=10)
    assert ide.logs() == ["42"]
    # the block travels with the program
    ide.page.click("#share")
    link = ide.page.wait_for_function("rosgateIde.lastShareLink").json_value()
    other = ide_factory(turtle_gateway, url=link)
    assert other.js("rosgateIde.workspace.getAllBlocks(false).some(b => b.type === 'my_service_add_two_ints')")
    assert "my_service_add_two_ints" in other.js("JSON.stringify(rosgateIde.workspace.getToolbox().getToolboxItems().map(i => i.getContents?.()))")


def test_step_pause_and_resume(turtle_gateway, turtle_ros, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(
        {**ex.log(ex.text("a")), "id": "A"}, {**ex.log(ex.text("b")), "id": "B"}, {**ex.log(ex.text("c")), "id": "C"})))
    highlighted = "rosgateIde.runner.rt && rosgateIde.runner.rt.current"
    ide.page.click("#step")                     # the first press runs the first block
    ide.page.wait_for_function(f"{highlighted} === 'B'")
    assert ide.js("document.body.dataset.run") == "paused" and ide.logs() == ["a"]
    ide.page.click("#step")
    ide.page.wait_for_function(f"{highlighted} === 'C'")
    assert ide.logs() == ["a", "b"]
    ide.page.click("#run")                      # resume
    ide.wait_idle(timeout=5)
    assert ide.logs() == ["a", "b", "c"]

    # pausing a driving program stops the robot; resuming drives on
    cmd = turtle_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(drive()))
    ide.run()
    wait_for(lambda: moving(cmd), what="driving")
    t0 = time.monotonic()
    ide.page.click("#pause")
    zero_at = wait_for(lambda: next((t for t, m in cmd.since(t0) if m["linear"]["x"] == 0), None),
                       timeout=1, what="zero on Pause")
    assert ide.js("document.body.dataset.run") == "paused"
    t1 = time.monotonic()
    assert not any(m["linear"]["x"] != 0 for t, m in cmd.since(zero_at) if t < t1)
    ide.page.click("#run")
    wait_for(lambda: moving(cmd, t1), timeout=2, what="driving again after Resume")
    ide.page.click("#stop")
    ide.wait_idle(timeout=2)


def test_a_run_is_under_way_from_the_press_and_stop_cancels_it_before_its_first_block(turtle_gateway, ide_factory):
    """Run may wait for the graph (a loaded machine reads it slowly): the page shows the run at
    once, and Stop meanwhile means none of its blocks runs."""
    ide = ide_factory(turtle_gateway)
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(ex.log(ex.text("first")))))
    ide.js("() => { rosgateIde.runner.ready = () => new Promise((r) => { window.graphRead = r; }); }")
    ide.run()
    assert ide.js("document.body.dataset.run") == "running"
    ide.page.click("#stop")
    assert ide.js("document.body.dataset.run") == "idle"
    ide.js("() => window.graphRead()")
    ide.run()                                 # the next run, once the graph is read, runs its blocks
    assert ide.js("document.body.dataset.run") == "running"
    ide.js("() => window.graphRead()")
    ide.wait_idle()
    assert ide.logs() == ["first"]
    assert not ide.errors, ide.errors
