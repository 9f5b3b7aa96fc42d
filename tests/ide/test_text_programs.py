"""Text programs in Chromium, typed into the editor (CodeMirror's .cm-content) as a student types:
a JavaScript program drives turtle1 (its pose moves, seen by an independent roslibpy client) and
Stop zeroes it within 0.5 s of the click; an error is marked on its line (a syntax error before
the run); completion offers the live graph's names and a name the graph lacks is underlined; an
example made text ("Edit as text") runs the same square in the page, and its Python, downloaded,
runs the same square with roslibpy against the gateway; the text program is kept by autosave and
a share link. One gateway and one browser page for the module."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from tests.support.ide import ARTIFACTS, PHONE, IdePage, error_line, open_text, page_errors
from tests.support.ros import LOOP_REACH, START, reset_turtlesim
from tests.support.wait import wait_for

TWIST = "geometry_msgs/msg/Twist"
POSE = "turtlesim/msg/Pose"


@pytest.fixture(scope="module")
def ide(chromium, turtle_gateway):
    ctx = chromium.new_context(viewport={"width": 1400, "height": 860}, accept_downloads=True)
    page = IdePage(ctx.new_page(), turtle_gateway)
    yield page
    ctx.close()


def type_program(ide: IdePage, lines: list[str]):
    """Types each line at the end of the text, as keys; the editor closes brackets and quotes
    itself and steps over the ones typed after them."""
    ide.page.click(".cm-content")
    ide.page.keyboard.press("Control+End")
    ide.page.keyboard.type("\n".join(lines), delay=2)
    assert ide.js("rosgateIde.textMode.text") == "\n".join(lines)


def went_round_the_square(pose, cmd, tol: float = 4 * LOOP_REACH):
    """drive_square.json's motion: the four corners of a square of side 3 from the start and back,
    the robot still at the end, each corner within what four closed-loop moves and turns may add up to."""
    corners = [(START, START), (START + 3, START), (START + 3, START + 3), (START, START + 3)]
    seen = [m for _, m in pose.messages]
    for x, y in corners:
        assert any(abs(m["x"] - x) < tol and abs(m["y"] - y) < tol for m in seen), (x, y)
    end = pose.latest()
    assert abs(end["x"] - START) < tol and abs(end["y"] - START) < tol, end
    # the run's end is the page's word; the zero reaches this other connection a moment later
    wait_for(lambda: cmd.latest()["linear"]["x"] == 0 and cmd.latest()["angular"]["z"] == 0, timeout=30,
             what="the zero as the last command")


DRIVE = [
    "const cmd = new ROSLIB.Topic({ ros, name: '/turtle1/cmd_vel', messageType: 'geometry_msgs/msg/Twist' });",
    "console.log('driving', 1 + 1);",
    "setInterval(() => cmd.publish({ linear: { x: 0.5 }, angular: { z: 0.4 } }), 50);",
]


def test_javascript_drives_and_stop_zeroes_it(ide, turtle):
    open_text(ide, "javascript")
    type_program(ide, DRIVE)
    pose = turtle.watch("/turtle1/pose", POSE)
    cmd = turtle.watch("/turtle1/cmd_vel", TWIST)
    start = wait_for(pose.latest, what="a pose")
    ide.js("""(() => {
      rosgateIde.sent = [];
      const ros = rosgateIde.ros, send = ros.callOnConnection.bind(ros);
      ros.callOnConnection = (m) => {
        if (m.op === 'publish' && m.topic === '/rosgate/program') rosgateIde.sent.push(JSON.parse(m.msg.data));
        send(m);
      };
    })()""")
    ide.page.click("#run")
    ide.page.wait_for_function("document.body.dataset.run === 'running'")
    wait_for(lambda: (p := pose.latest()) and abs(p["x"] - start["x"]) + abs(p["y"] - start["y"]) > 0.3,
             what="turtle1 moving under the program")
    assert "driving 2" in ide.logs()
    # the running line: the publish in the interval's callback, in the editor and in the report
    # the class view's tile shows (NS/rosgate/program; this gateway has no stations, so the
    # report is read where the page sends it)
    ide.page.wait_for_selector(".cm-running-line[data-line='3']")
    report = ide.page.wait_for_function("rosgateIde.sent.find((r) => r.line === 3 && r.state === 'running')").json_value()
    assert report["program"]["kind"] == "text" and report["program"]["text"] == "\n".join(DRIVE)
    t0 = time.monotonic()
    ide.page.click("#stop")
    zero = wait_for(lambda: next((t for t, m in cmd.since(t0) if not m["linear"]["x"] and not m["angular"]["z"]), None),
                    timeout=2, what="a zero Twist after Stop")
    latency = zero - t0
    print(f"Stop -> zero Twist: {latency * 1000:.0f} ms")
    # the 0.5 s is the figure printed above (a quiet machine: 49-172 ms); the bound here is one a
    # busy 2-core CI machine keeps too, and a Stop that did not zero the robot misses
    assert latency < 1.5, latency
    ide.page.wait_for_function("document.body.dataset.run === 'idle'")
    time.sleep(0.3)   # the interval would have published six times by now
    assert all(not m["linear"]["x"] for _, m in cmd.since(zero + 0.01)), "the program went on after Stop"
    assert not ide.page.query_selector(".cm-running-line")
    assert not page_errors(ide)


def test_errors_are_marked_on_their_line(ide):
    open_text(ide, "javascript")
    type_program(ide, ["import { rt } from 'rosgate';", "rt.log('one');", "", "rt.field({ a: 1 }, 'b.c');", "rt.log('two');"])
    ide.page.click("#run")
    assert error_line(ide) == 4
    ide.page.wait_for_selector(".cm-lintRange-error")       # the lint's error too, with its gutter mark
    assert ide.page.query_selector(".cm-lint-marker-error")
    ide.page.wait_for_function("document.body.dataset.run === 'idle'")
    assert "line 4:" in ide.console_text()
    assert ide.logs()[-1] == "one"
    # a syntax error: marked before the program runs (nothing is logged)
    ide.page.click(".cm-content")
    ide.page.keyboard.press("Control+a")
    ide.page.keyboard.press("Delete")
    ide.page.keyboard.type("console.log('never');\nlet a = 1;\nlet b = (a + 2;\nconsole.log(b);")
    # marked as it is typed (JavaScript's own parse, once the typing pauses)
    assert ide.page.wait_for_selector(".cm-lintRange-error").inner_text() == "let b = (a + 2;"
    logs = len(ide.logs())
    ide.page.click("#run")
    assert error_line(ide) == 3
    assert len(ide.logs()) == logs
    assert "line 3: SyntaxError" in ide.console_text()
    ide.page.click(".cm-content")
    ide.page.keyboard.press("Control+End")
    ide.page.keyboard.type("\n")            # an edit clears the mark
    ide.page.wait_for_selector(".cm-error-line", state="detached")


def test_completion_offers_the_graph(ide):
    open_text(ide, "python")
    ide.page.click(".cm-content")
    ide.page.keyboard.press("Control+a")      # a new Python program holds a short one: typed over
    ide.page.keyboard.press("Delete")
    ide.page.keyboard.type("rt.publish('/turtle1/cm")
    item = ide.page.locator(".cm-tooltip-autocomplete li:has-text('/turtle1/cmd_vel')")
    assert TWIST in item.inner_text()
    # one event: the option shown is the one taken; a locator finds it again if the list redraws
    item.click()
    ide.page.keyboard.type("', 'geometry_msgs/msg/Twist', {'li")      # ' steps over the closing quote
    fields = ".cm-tooltip-autocomplete li:has-text('linear')"
    try:    # the fields come from rosapi; a link the loaded machine dropped meanwhile is asked again
        ide.page.wait_for_selector(fields, timeout=10000)
    except Exception:
        ide.page.keyboard.press("Backspace")
        ide.page.keyboard.type("i")
        try:
            ide.page.wait_for_selector(fields, timeout=10000)
        except Exception:
            raise AssertionError(ide.js("""(async () => JSON.stringify({
              text: rosgateIde.textMode.text, tip: document.querySelector('.cm-tooltip-autocomplete')?.innerText,
              connected: rosgateIde.graph.connected, cached: rosgateIde.graph.cachedDetails('msg', 'geometry_msgs/msg/Twist'),
              details: await rosgateIde.graph.details('msg', 'geometry_msgs/msg/Twist').then((d) => d.length, (e) => e.message),
              focus: document.activeElement?.className }))()""")) from None
    ide.page.keyboard.press("Escape")
    assert ide.js("rosgateIde.textMode.text").startswith("rt.publish('/turtle1/cmd_vel', 'geometry_msgs/msg/Twist', {'li")
    # the runtime's functions with their arguments
    ide.page.keyboard.press("Control+End")
    ide.page.keyboard.type("\nrt.wait_for")
    ide.page.wait_for_selector(".cm-tooltip-autocomplete li:has-text('wait_for_message')")
    assert "timeout=0" in ide.page.inner_text(".cm-tooltip-autocomplete")
    ide.page.keyboard.press("Escape")
    # a name the graph lacks: underlined, not refused
    ide.page.keyboard.type("_message('/turtle1/nothing_here', 'std_msgs/msg/String')")
    ide.page.wait_for_selector(".cm-lintRange-warning")
    assert "nothing_here" in ide.js("rosgateIde.textMode.text")


def test_example_as_text_runs_the_same_square(ide, turtle, turtle_gateway):
    ide.open()
    ide.load_example("drive_square.json")
    blocks = ide.workspace()
    ide.page.click("[data-tab='code-js']")
    ide.page.click("#edit-text")
    ide.page.wait_for_function("rosgateIde.textMode.lang === 'javascript'")
    text = ide.js("rosgateIde.textMode.text")
    assert "import { rt } from 'rosgate';" in text and "rt.step" not in text
    pose = reset_turtlesim(turtle)
    cmd = turtle.watch("/turtle1/cmd_vel", TWIST)
    ide.page.click("#run")
    ide.page.wait_for_function("document.body.dataset.run === 'idle'", timeout=90000)
    assert "finished" in ide.console_text(), ide.console_text()
    went_round_the_square(pose, cmd)
    # the block program stays as it was
    ide.page.click("#to-blocks")
    ide.page.wait_for_function("document.body.dataset.mode === 'blocks'")
    assert ide.workspace() == blocks

    # the same example as Python text, downloaded, runs with roslibpy against the gateway
    ide.page.click("[data-tab='code-python']")
    ide.page.click("#edit-text")
    ide.page.wait_for_function("rosgateIde.textMode.lang === 'python'")
    text = ide.js("rosgateIde.textMode.text")
    assert "from rosgate_runtime import *" in text and "class Runtime" not in text
    with ide.page.expect_download() as dl:
        ide.page.click("#download-py")
    path = ARTIFACTS / "drive_square_text.py"
    dl.value.save_as(path)
    downloaded = path.read_text()
    # the student's lines are the file's lines (the runtime rides on the import line)
    assert len(downloaded.splitlines()) == len(text.splitlines())
    pose = reset_turtlesim(turtle)
    cmd = turtle.watch("/turtle1/cmd_vel", TWIST)
    proc = subprocess.run([sys.executable, str(path), "--url", turtle_gateway.ws_url],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    went_round_the_square(pose, cmd)


def test_text_program_is_kept(ide):
    open_text(ide, "javascript")
    type_program(ide, ["console.log('kept');"])
    ide.page.fill("#name", "kept one")
    ide.page.press("#name", "Enter")
    ide.page.wait_for_function("(s => s.text === \"console.log('kept');\" && s.name === 'kept one')"
                               "(JSON.parse(localStorage.getItem('rosgate.autosave') || '{}'))")
    ide.open()                                  # the autosave opens it again
    ide.page.wait_for_selector(".cm-content")
    assert ide.js("rosgateIde.program()")["kind"] == "text"
    assert ide.js("rosgateIde.textMode.text") == "console.log('kept');"
    ide.page.click("#share")
    link = ide.page.wait_for_function("rosgateIde.lastShareLink").json_value()
    ide.js("localStorage.clear()")
    ide.open(link)
    ide.page.wait_for_selector(".cm-content")
    assert ide.js("rosgateIde.program()") == {"format": "rosgate-program", "version": 1, "kind": "text",
                                              "lang": "javascript", "name": "kept one", "robot": "any",
                                              "text": "console.log('kept');"}


def test_a_phone_indents_with_buttons(chromium, turtle_gateway):
    """On a phone (390x844, touch) the toolbar indents and outdents without a Tab key, and Run and
    Stop stay in reach above the editor."""
    ctx = chromium.new_context(viewport=PHONE, has_touch=True, is_mobile=True)
    try:
        ide = IdePage(ctx.new_page(), turtle_gateway)
        open_text(ide, "python")
        ide.page.tap(".cm-content")
        ide.page.keyboard.press("Control+a")      # a new Python program holds a short one: typed over
        ide.page.keyboard.press("Delete")
        ide.page.keyboard.type("def main():\nrt.log('hi')")       # the editor indents the body itself
        ide.page.tap(".text-tools [data-cmd='outdent']")
        ide.page.tap(".text-tools [data-cmd='indent']")
        ide.page.tap(".text-tools [data-cmd='indent']")
        assert ide.js("rosgateIde.textMode.text") == "def main():\n        rt.log('hi')"
        ide.page.tap(".text-tools [data-cmd='undo']")
        assert ide.js("rosgateIde.textMode.text") == "def main():\n    rt.log('hi')"
        for sel in ("#run", "#stop", ".text-tools [data-cmd='indent']", "#new", "#new-text", "#to-blocks",
                    "#library", "#upload", "#download", "#download-py", "#share"):
            box = ide.page.locator(sel).bounding_box()
            assert box and box["x"] >= 0 and box["x"] + box["width"] <= PHONE["width"], (sel, box)
        editor = ide.page.locator("#text-editor").bounding_box()
        assert editor["width"] >= PHONE["width"] - 2 and editor["height"] > 300, editor
        ide.screenshot("text-phone")
        assert not page_errors(ide)
    finally:
        ctx.close()
