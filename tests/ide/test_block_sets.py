"""A robot's block set without editing code: a JSON file in the gateway's --blocks-dir is listed in
the IDE's toolbox for the robot it names, its blocks generate code that drives the sim turtle; a
block the teacher makes is published to the class (an admin's POST) and another student's IDE lists
it; a student's publish is refused (403)."""

from __future__ import annotations

import json
import roslibpy

from tests.support.http import http
from tests.support.ide import IdePage, program
from tests.support.lesson import TOKENS, tokens_file
from tests.support.wait import wait_for

TURTLE_SET = {
    "name": "Turtle extras", "colour": 160, "robot": "/",
    "blocks": [{
        "type": "extra_forward", "message0": "forward at %1 m/s for %2 s",
        "args0": [{"type": "input_value", "name": "SPEED", "check": "Number"},
                  {"type": "input_value", "name": "SECONDS", "check": "Number"}],
        "inputsInline": True, "previousStatement": None, "nextStatement": None,
        "rosgate": {"kind": "drive", "topic": "/turtle1/cmd_vel", "type": "geometry_msgs/msg/Twist",
                    "msg": {"linear": {"x": "$SPEED", "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}},
                    "seconds": "$SECONDS"},
    }],
}
HUSKY_SET = {"name": "Husky arm", "robot": "/husky*", "blocks": [{"type": "husky_wave", "message0": "wave",
                                                                  "previousStatement": None, "nextStatement": None}]}
NUM = lambda v: {"shadow": {"type": "math_number", "fields": {"NUM": v}}}


def categories(ide: IdePage) -> list[str]:
    return ide.js("rosgateIde.workspace.getToolbox().getToolboxItems().map((i) => i.getName?.() ?? '')")


def test_block_sets_and_the_class_library(start_gateway, tablets, tmp_path):
    blocks = tmp_path / "blocks"
    blocks.mkdir()
    (blocks / "turtle_extras.json").write_text(json.dumps(TURTLE_SET))
    (blocks / "husky.json").write_text(json.dumps(HUSKY_SET))
    (blocks / "broken.json").write_text("{ not json")
    gw = start_gateway("--robot", "turtlesim", "--auth", tokens_file(tmp_path), "--blocks-dir", str(blocks))

    teacher = IdePage(tablets(gw, "teacher").new_page(), gw).open()
    # the turtle's set is listed for this robot, the Husky's is not; the broken file hides itself alone
    names = categories(teacher)
    assert "Turtle extras" in names and "Husky arm" not in names, names
    listed = json.loads(http(gw, "/api/blocks", token=TOKENS["teacher"]).body)
    assert [s["file"] for s in listed["skipped"]] == ["broken.json"] and listed["publish"] is True

    # its block generates code that drives the turtle
    teacher.js("(p) => rosgateIde.loadProgram(p)", program(
        {"type": "extra_forward", "inputs": {"SPEED": NUM(0.7), "SECONDS": NUM(1.5)}}, name="extras"))
    assert "/turtle1/cmd_vel" in teacher.javascript() and "/turtle1/cmd_vel" in teacher.python()
    ros = roslibpy.Ros(f"ws://{gw.host}:{gw.port}/?token={TOKENS['teacher']}")
    ros.run(timeout=10)
    seen = []
    roslibpy.Topic(ros, "/turtle1/cmd_vel", "geometry_msgs/msg/Twist").subscribe(seen.append)
    try:
        wait_for(lambda: ros.is_connected, what="the watcher")
        teacher.run()
        wait_for(lambda: any(abs(m["linear"]["x"] - 0.7) < 1e-9 for m in seen), timeout=10, what="the set's block driving")
        teacher.wait_idle()
        wait_for(lambda: seen and seen[-1]["linear"]["x"] == 0, timeout=5, what="zero at the block's end")
    finally:
        ros.close()

    # the teacher makes a block and publishes it to the class
    teacher.make_block("publish", "/turtle1/cmd_vel", "class drive", "my_publish_turtle1_cmd_vel")
    toolbox = "JSON.stringify(rosgateIde.workspace.getToolbox().toolboxDef_)"
    assert "publishBlocks" in teacher.js(toolbox)   # the admin's button, under My blocks
    assert teacher.js("rosgateIde.publishBlocks()") == 1
    assert "published" in teacher.console_text()
    stored = json.loads((blocks / "shared.json").read_text())
    assert [m["json"]["type"] for m in stored["made"]] == ["my_publish_turtle1_cmd_vel"]

    # another student's IDE lists it and can use it; a program using it carries its definition
    ada = IdePage(tablets(gw, "ada").new_page(), gw).open()
    assert "Class blocks" in categories(ada)
    assert ada.js("!!Blockly.Blocks['my_publish_turtle1_cmd_vel']")
    assert ada.js("rosgateIde.blockSets.publishable") is False
    ada.js("(p) => rosgateIde.loadProgram(p)", program({"type": "my_publish_turtle1_cmd_vel"}, name="with a class block"))
    ada.js("rosgateIde.workspace.newBlock('my_publish_turtle1_cmd_vel').initSvg()")
    assert "my_publish_turtle1_cmd_vel" in [b["json"]["type"] for b in ada.js("rosgateIde.program().blocks")]
    assert "/turtle1/cmd_vel" in ada.javascript()
    assert "publishBlocks" not in ada.js(toolbox)

    # a student's publish: 403, and the library is as it was
    status = ada.js("""fetch('api/blocks/shared', {method: 'POST', headers: {'Content-Type': 'application/json'},
                       body: JSON.stringify({json: {type: 'ada_block'}, spec: {}})}).then((r) => r.status)""")
    assert status == 403
    refused = http(gw, "/api/blocks/shared", method="POST", json={"json": {"type": "x"}, "spec": {}}, token=TOKENS["ada"])
    assert refused.status == 403 and b"admin" in refused.body
    assert json.loads((blocks / "shared.json").read_text()) == stored
    expected = "status of 403"   # the refused publish above, as the browser logs it
    assert not teacher.errors and not [e for e in ada.errors if expected not in e], (teacher.errors, ada.errors)


def test_a_set_is_listed_for_the_station_its_glob_names(start_gateway, ide_factory, tmp_path):
    for ns in ("/s01", "/s02"):
        (tmp_path / f"set{ns[1:]}.json").write_text(json.dumps(
            {"name": f"Blocks of {ns}", "robot": ns, "blocks": [{"type": f"only_{ns[1:]}", "message0": ns}]}))
    (tmp_path / "every.json").write_text(json.dumps({"name": "Every robot", "blocks": [{"type": "every_one", "message0": "x"}]}))
    gw = start_gateway("--robot", "turtlesim", "--fleet", "2", "--blocks-dir", str(tmp_path))
    ide = ide_factory(gw, gw.http_url + "?ns=/s02")
    ide.page.wait_for_function("rosgateIde.ns === '/s02'")
    names = categories(ide)
    assert "Blocks of /s02" in names and "Every robot" in names and "Blocks of /s01" not in names, names
    assert not ide.errors, ide.errors
