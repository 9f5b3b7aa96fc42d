"""A Python text program from end to end in Chromium, on `--robot turtlesim` without --allow-runs:
`/?mode=text&lang=python`, the program typed into the editor (.cm-content) as a student types
it, run with the real js/run/pyrun.js (Pyodide in a worker) behind js/run/textrun.js's door. A textbook
roslibpy program (`roslibpy.Ros(host='example.org', port=9090)`, `run()`, a `Topic` publish,
`time.sleep`) drives turtle1 (an independent roslibpy client sees its pose move) and its prints
reach the IDE's console; Stop zeroes the turtle and nothing drives after; a runtime error is
marked on its line, a syntax error before the run; a program that ends says so, and one that
stops says why. A newcomer's first minutes: a new program that runs as it opens (Python loading
as it opens), top-level lines without main(), timers and served services in the page. One gateway
and one browser page for the module (and a fresh page for the new program)."""

from __future__ import annotations

import time

import pytest

from tests.support.ide import IdePage, error_line, open_text, page_errors
from tests.support.wait import wait_for

TWIST = "geometry_msgs/msg/Twist"
POSE = "turtlesim/msg/Pose"

PYODIDE_START = 120   # s: Pyodide's cold start on a busy 2-core machine


@pytest.fixture(scope="module")
def ide(chromium, turtle_gateway):
    ctx = chromium.new_context(viewport={"width": 1400, "height": 860})
    page = IdePage(ctx.new_page(), turtle_gateway)
    open_text(page, "python")
    yield page
    ctx.close()


def type_python(ide: IdePage, lines: list[str]):
    """Replaces the text with `lines`, typed key by key. After each Enter the editor indents the
    new line as Python's blocks suggest; Shift-Tab (the editor's outdent) takes that back and the
    line is typed with its own indentation, as a student fixing the editor's guess would."""
    ide.page.click(".cm-content")
    ide.page.keyboard.press("Control+a")
    ide.page.keyboard.press("Delete")
    for i, line in enumerate(lines):
        if i:
            ide.page.keyboard.press("Enter")
            for _ in range(3):
                ide.page.keyboard.press("Shift+Tab")
        ide.page.keyboard.type(line, delay=2)
    assert ide.js("rosgateIde.textMode.text") == "\n".join(lines)


def run_to_its_end(ide: IdePage, lines: list[str]) -> int:
    """Types the program, presses Run and waits for the run to end; the run's number."""
    type_python(ide, lines)
    runs = ide.js("rosgateIde.textRunner.runs")
    ide.page.click("#run")
    ide.page.wait_for_function(f"rosgateIde.textRunner.runs > {runs}")
    ide.page.wait_for_function("document.body.dataset.run === 'idle'", timeout=PYODIDE_START * 1000)
    return runs + 1


DRIVE = [
    "import time",
    "import roslibpy",
    "",
    "ros = roslibpy.Ros(host='example.org', port=9090)",
    "ros.run()",
    "cmd = roslibpy.Topic(ros, '/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')",
    "print('driving', 2 * 3)",
    "for i in range(2000):",
    "    twist = {'linear': {'x': 0.6, 'y': 0.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': 0.5}}",
    "    cmd.publish(roslibpy.Message(twist))",
    "    time.sleep(0.05)",
    "print('not reached')",
]


def test_python_drives_the_turtle_and_stop_zeroes_it(ide, turtle):
    pose = turtle.watch("/turtle1/pose", POSE)
    cmd = turtle.watch("/turtle1/cmd_vel", TWIST)
    start = wait_for(pose.latest, what="a pose")
    type_python(ide, DRIVE)
    ide.page.click("#run")
    ide.page.wait_for_function("document.body.dataset.run === 'running'")
    # Pyodide loads at the first Python run of the page
    try:
        wait_for(lambda: (p := pose.latest()) and abs(p["x"] - start["x"]) + abs(p["y"] - start["y"]) > 0.3,
                 timeout=PYODIDE_START, what="turtle1 moving under the Python program")
    except AssertionError as e:
        raise AssertionError(f"{e}; run {ide.js('document.body.dataset.run')}; console:\n{ide.console_text()}"
                             f"\npage errors: {ide.errors}\nlast pose {pose.latest()}, {len(cmd.messages)} commands") from e
    assert "driving 6" in ide.logs()
    assert ide.js("document.body.dataset.run") == "running"
    # the running line: one of the loop's lines, marked in the editor
    ide.page.wait_for_selector(".cm-running-line")
    assert 8 <= int(ide.page.get_attribute(".cm-running-line", "data-line")) <= 11
    t0 = time.monotonic()
    ide.page.click("#stop")
    zero = wait_for(lambda: next((t for t, m in cmd.since(t0) if not m["linear"]["x"] and not m["angular"]["z"]), None),
                    what="a zero Twist after Stop")   # how soon: `python -m tests.bench stop` (bar 0.5 s)
    ide.page.wait_for_function("document.body.dataset.run === 'idle'")
    # the program's loop would have published ten times by now: none of it left the page
    wait_for(lambda: time.monotonic() > zero + 0.5, what="half a second")
    assert all(not m["linear"]["x"] for _, m in cmd.since(zero + 0.01)), "the Python program went on after Stop"
    assert "not reached" not in ide.logs()
    assert not ide.page.query_selector(".cm-running-line")


ERROR = [
    "import time",
    "print('before the error')",
    "time.sleep(0.1)",
    "values = [1, 2, 3]",
    "print(values[7])",
]


def test_a_runtime_error_is_marked_on_its_line(ide):
    run_to_its_end(ide, ERROR)
    assert error_line(ide) == 5
    text = ide.console_text()
    assert "before the error" in text
    assert "IndexError" in text and "line 5" in text
    assert 'File "<program>", line 5' in text           # the traceback's line is the student's


def test_a_syntax_error_is_marked_before_the_run(ide, turtle):
    cmd = turtle.watch("/turtle1/cmd_vel", TWIST)
    t0 = time.monotonic()
    run_to_its_end(ide, ["x = 1", "print('never printed')", "if x > 0", "    x = 2"])
    assert error_line(ide) == 3
    assert "never printed" not in ide.logs() and "SyntaxError" in ide.console_text()
    assert not cmd.since(t0)


FINISH = [
    "import roslibpy",
    "client = roslibpy.Ros(host='example.org', port=9090)",
    "client.run()",
    "def square(n):",
    "    return n * n",
    "print('squares', [square(k) for k in range(4)], client.is_connected)",
    "client.terminate()",
]


def test_a_program_that_ends_says_so(ide):
    n = run_to_its_end(ide, FINISH)
    assert "squares [0, 1, 4, 9] True" in ide.logs()
    assert f"run {n} finished" in ide.console_text()
    assert not ide.page.query_selector(".cm-error-line")
    assert not page_errors(ide)


# ---- a newcomer's first minutes -------------------------------------------------------------------

def test_a_new_python_program_is_a_short_one_that_runs(ide_factory, turtle_gateway, turtle):
    """"New Python" opens a program (not a grey placeholder) that runs as it is: its lines at the top
    level, no main(), no run(); Python loaded as the program opened, the bar saying when it is ready."""
    cmd = turtle.watch("/turtle1/cmd_vel", TWIST)
    ide = ide_factory(turtle_gateway)
    requests_before = len(ide.requests)
    open_text(ide, "python")
    text = ide.js("rosgateIde.textMode.text")
    assert text.strip() and "rt.publish(" in text and "def main" not in text and "run(main)" not in text
    # Pyodide loads now, before any Run, and the bar says so
    ide.page.wait_for_selector(".text-python[data-state='ready']", timeout=PYODIDE_START * 1000)
    assert any("/vendor/pyodide/" in u and u.endswith(".wasm") for u in ide.requests[requests_before:])
    assert "Python ready (" in ide.page.inner_text(".text-python")
    assert ide.js("rosgateIde.link.busy") == 0           # the link's patience ended with the load
    t0 = time.monotonic()
    ide.page.click("#run")
    ide.page.wait_for_function("document.body.dataset.run === 'idle'", timeout=PYODIDE_START * 1000)
    logs = ide.logs()
    assert "driving turtle1 forward for a second" in logs and "done" in logs, ide.console_text()
    assert any(m["linear"]["x"] == 1.0 for _, m in cmd.since(t0))
    assert "finished" in ide.console_text()
    assert not page_errors(ide)


SERVING = [
    "from rosgate_runtime import *",
    "",
    "ticks = []",
    "rt.every(0.1, lambda: ticks.append(1))",
    "",
    "def add(request):",
    "    return {'sum': request['a'] + request['b']}",
    "",
    "rt.serve_service('/page/add', 'example_interfaces/srv/AddTwoInts', add)",
    "rt.sleep(1)",
    "print('ticking', len(ticks) >= 3)",
]
ROSLIBPY_SERVING = [
    "import roslibpy",
    "",
    "ros = roslibpy.Ros('localhost', 9090)",
    "ros.run()",
    "",
    "def handler(request, response):",
    "    response['success'] = request['data']",
    "    response['message'] = 'set from the page'",
    "    return True",
    "",
    "roslibpy.Service(ros, '/page/set', 'std_srvs/srv/SetBool').advertise(handler)",
    "ros.call_later(0.3, lambda: print('later'))",
    "ros.run_forever()",
]


def test_timers_and_served_services_work_in_the_page(ide, turtle):
    """The runtime's every and serve_service at the top level (no main()), and a roslibpy server with
    call_later: served through the gateway while the program waits; Stop ends them."""
    type_python(ide, SERVING)
    ide.page.click("#run")
    ide.logged('ticking True', PYODIDE_START)
    assert turtle.call("/page/add", "example_interfaces/srv/AddTwoInts", {"a": 2, "b": 40})["sum"] == 42
    assert ide.js("document.body.dataset.run") == "running"     # its handlers keep it going
    ide.page.click("#stop")
    ide.page.wait_for_function("document.body.dataset.run === 'idle'")
    type_python(ide, ROSLIBPY_SERVING)
    ide.page.click("#run")
    ide.logged('later', PYODIDE_START)
    answer = wait_for(lambda: _call(turtle, "/page/set", "std_srvs/srv/SetBool", {"data": True}), what="/page/set")
    assert answer == {"success": True, "message": "set from the page"}
    ide.page.click("#stop")
    ide.page.wait_for_function("document.body.dataset.run === 'idle'")
    assert "stopped: Stop was pressed" in ide.console_text()


def _call(turtle, service, type_, args):
    try:
        return turtle.call(service, type_, args, timeout=5)
    except Exception:   # noqa: BLE001: not served yet
        return None


def test_a_run_the_lost_link_ends_says_why(ide, turtle):
    type_python(ide, DRIVE)
    ide.page.click("#run")
    ide.logged('driving 6', PYODIDE_START)
    ide.js("rosgateIde.link._lose('silent')")      # what the link does when the gateway falls silent
    ide.page.wait_for_function("document.body.dataset.run === 'idle'")
    assert "■ stopped: the link to the gateway was lost (robot stopped)" in ide.console_text()
    ide.page.wait_for_function("document.body?.dataset.connection === 'connected'", timeout=30000)
