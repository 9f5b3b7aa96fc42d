"""Each example's generated JavaScript and Python, checked per language in the real IDE page."""

from __future__ import annotations

import ast
import json
import sys

import pytest

from tests.support.ide import EXAMPLES

INDEX = json.loads((EXAMPLES / "index.json").read_text())["examples"]

# What each program must do, in both languages: (javascript, python) fragments.
EXPECT = {
    "drive_square.json": [
        ("await rt.callService(rt.ns('/turtle1/set_pen'), 'turtlesim/srv/SetPen', {r: 255, g: 220, b: 0, width: 4, off: 0});",
         "rt.call_service(rt.ns('/turtle1/set_pen'), 'turtlesim/srv/SetPen', {'r': 255, 'g': 220, 'b': 0, 'width': 4, 'off': 0})"),
        ("for (var count = 0; count < 4; count++) {", "for count in range(4):"),
        ("await rt.move({cmd: rt.ns('/turtle1/cmd_vel'), type: 'geometry_msgs/msg/Twist', pose: rt.ns('/turtle1/pose'), "
         "pose_type: 'turtlesim/msg/Pose'}, 3, 2);",
         "rt.move({'cmd': rt.ns('/turtle1/cmd_vel'), 'type': 'geometry_msgs/msg/Twist', 'pose': rt.ns('/turtle1/pose'), "
         "'pose_type': 'turtlesim/msg/Pose'}, 3, 2)"),
        ("await rt.turn(", "rt.turn("),
        ("rt.log('square done');", "rt.log('square done')"),
    ],
    "spiral.json": [
        ("for (i = 1; i <= 8; i++) {", "for i in range(1, 9):"),
        ("i * 0.4, 2);", "i * 0.4, 2)"),
        ("60, 180);", "60, 180)"),
    ],
    "three_turtles.json": [
        ("await rt.callService(rt.ns('/spawn'), 'turtlesim/srv/Spawn', {x: i * 2.5, y: 2, theta: (90) * Math.PI / 180, name: name2});",
         "rt.call_service(rt.ns('/spawn'), 'turtlesim/srv/Spawn', {'x': i * 2.5, 'y': 2, 'theta': math.radians(90), 'name': name})"),
        ("cmd: rt.ns('/' + name2 + '/cmd_vel')", "'cmd': rt.ns('/' + str(name) + '/cmd_vel')"),
    ],
    "wall_follower.json": [
        ("rt.rangeAt((await rt.latest(rt.ns('/scan'), 'sensor_msgs/msg/LaserScan')), (-90), 30)",
         "range_at(rt.latest(rt.ns('/scan'), 'sensor_msgs/msg/LaserScan'), -90, 30)"),
        ("rt.publish(rt.ns('/cmd_vel'), 'geometry_msgs/msg/Twist', {linear: {x: 0.3, y: 0, z: 0}, angular: {x: 0, y: 0, z: (25) * Math.PI / 180}});",
         "rt.publish(rt.ns('/cmd_vel'), 'geometry_msgs/msg/Twist', {'linear': {'x': 0.3, 'y': 0, 'z': 0}, 'angular': {'x': 0, 'y': 0, 'z': math.radians(25)}})"),
        ("await rt.sleep(0.1);", "rt.sleep(0.1)"),
    ],
    "pid_goal.json": [
        ("(await rt.latest(rt.ns('/odom'), 'nav_msgs/msg/Odometry', 'pose.pose.position.x'))",
         "rt.latest(rt.ns('/odom'), 'nav_msgs/msg/Odometry', 'pose.pose.position.x')"),
        ("rt.yaw((await rt.latest(rt.ns('/odom'), 'nav_msgs/msg/Odometry', 'pose.pose.orientation'))) * 180 / Math.PI",
         "math.degrees(yaw(rt.latest(rt.ns('/odom'), 'nav_msgs/msg/Odometry', 'pose.pose.orientation')))"),
        ("while (distance > 0.1) {", "while distance > 0.1:"),
    ],
    "fibonacci.json": [
        ("result = await rt.sendGoal('/fibonacci', 'example_interfaces/action/Fibonacci', {order: 8}, async (message) => {",
         "result = rt.send_goal('/fibonacci', 'example_interfaces/action/Fibonacci', {'order': 8}, on_feedback)"),
        ("rt.log(rt.field(feedback, 'sequence'));", "rt.log(field(feedback, 'sequence'))"),
        ("rt.log(rt.field(result, 'sequence'));", "rt.log(field(result, 'sequence'))"),
    ],
}

STDLIB = set(sys.stdlib_module_names)


@pytest.fixture(scope="module")
def ide(chromium, start_gateway):
    gw = start_gateway()
    ctx = chromium.new_context(viewport={"width": 1400, "height": 860})
    from tests.support.ide import IdePage
    page = IdePage(ctx.new_page(), gw).open()
    yield page
    ctx.close()


def test_index_lists_every_example():
    files = {e["file"] for e in INDEX}
    assert files == set(EXPECT)
    for e in INDEX:
        program = json.loads((EXAMPLES / e["file"]).read_text())
        assert program["format"] == "rosgate-program"
        assert e["title"] and e["robot"] in ("turtlesim", "rover", "any")


@pytest.mark.parametrize("file", sorted(EXPECT))
def test_generated_code(ide, file):
    program = ide.load_example(file)
    js = ide.javascript()
    py = ide.python()
    for js_part, py_part in EXPECT[file]:
        assert js_part in js, f"{file}: JavaScript lacks {js_part!r}\n{js}"
        assert py_part in py, f"{file}: Python lacks {py_part!r}\n{py[py.index('# --- end of'):]}"

    # the Python file is a whole program that needs nothing but roslibpy (what the runtime imports
    # under `if BROWSER:` is Pyodide's, in the page)
    tree = ast.parse(py)
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "BROWSER":
            node.body = []
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported.add(node.module.split(".")[0])
    assert imported - STDLIB == {"roslibpy"}, imported
    assert py.startswith(f'"""{program["name"]}: a rosgate block program.')
    assert py.rstrip().endswith("run(main)")

    # the instrumented JavaScript compiles, and every statement block reports itself
    instrumented = ide.js("rosgateIde.generateJs(true)")
    ide.js("(code) => { new (Object.getPrototypeOf(async () => {}).constructor)('rt', code); }", instrumented)
    ids = ide.js("rosgateIde.workspace.getAllBlocks(false).filter(b => b.previousConnection && !b.isShadow()).map(b => b.id)")
    for block_id in ids:
        assert f"await rt.step('{block_id}');" in instrumented, block_id
    assert not ide.errors, ide.errors


def test_code_panel_updates_live(ide):
    ide.load_example("drive_square.json")
    ide.page.wait_for_function("document.querySelector('#code-python').textContent.includes('square done')")
    ide.js("""() => {
        const b = rosgateIde.workspace.getAllBlocks(false).find(b => b.type === 'text' && b.getFieldValue('TEXT') === 'square done');
        b.setFieldValue('all four sides', 'TEXT');
    }""")
    ide.page.wait_for_function("document.querySelector('#code-python').textContent.includes(\"rt.log('all four sides')\")")
    assert "the rosgate runtime" in ide.page.inner_text("#code-python")
    ide.page.click("[data-tab=code-js]")
    ide.page.wait_for_function("document.querySelector('#code-js').textContent.includes(\"rt.log('all four sides');\")")
    assert ide.page.is_visible("#code-js") and not ide.page.is_visible("#code-python")
