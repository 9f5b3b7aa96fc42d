"""Python in the IDE page (ide/js/run/pyrun.js): Pyodide in a worker over the page's own connection, in
Chromium, on `--robot turtlesim` without --allow-runs. Each program is run through the module's API
(runPython, stopPython, checkPython) with the page's connected Ros; an independent roslibpy client
watches what the turtle does."""

from __future__ import annotations

import math
import time

import pytest

from tests.support.ide import PY_DRIVE
from tests.support.wait import wait_for

START = """async ({source, ns}) => {
  const py = await import('/js/run/pyrun.js');
  const out = window.pyOut = {logs: [], lines: [], errors: [], done: false};
  window.pyDone = py.runPython(source, {
    ros: rosgateIde.ros, namespace: ns,
    log: (text, level) => out.logs.push([level, text]),
    onLine: (n) => out.lines.push(n),
    onError: (e) => out.errors.push(e),
  }).then(() => { out.done = true; out.doneAt = performance.now(); });
  return true;
}"""
PYODIDE_START = 90   # s: a cold start on a busy 2-core machine


@pytest.fixture(scope="module")
def ide(chromium, turtle_gateway):
    from .conftest import IdePage
    ctx = chromium.new_context(viewport={"width": 1400, "height": 860})
    page = IdePage(ctx.new_page(), turtle_gateway).open()
    yield page
    page.js("async () => (await import('/js/run/pyrun.js')).stopPython()")
    ctx.close()


def start(ide, source: str, ns: str = ""):
    ide.js(START, {"source": source, "ns": ns})


def lost(ide) -> str:
    return ide.js("JSON.stringify(rosgateIde.link?.lastLost ?? null)")


def start_until(ide, source: str, predicate, what: str):
    """Starts the program and waits until predicate() holds. A program that ends first fails the
    test with what the page said, unless the page lost its link meanwhile (a starved machine: the
    page rightly stops a program whose link is gone): then it is started again on the new link."""
    for _ in range(3):
        ide.page.wait_for_function("document.body.dataset.connection === 'connected'", timeout=60000)
        before = lost(ide)
        start(ide, source)
        if wait_for(lambda: predicate() or (out(ide)["done"] and "ended"), timeout=PYODIDE_START, what=what) is True:
            return
        if lost(ide) == before:
            raise AssertionError(f"the program ended before {what}: {out(ide)}")
    raise AssertionError(f"{what}: the page lost its link at each of 3 starts; the last: {lost(ide)}")


def out(ide) -> dict:
    return ide.js("window.pyOut")


def finish(ide, timeout: float = PYODIDE_START) -> dict:
    ide.page.wait_for_function("window.pyOut.done", timeout=timeout * 1000)
    return out(ide)


def logged(ide, level: str | None = None) -> str:
    return "\n".join(t for lv, t in out(ide)["logs"] if level is None or lv == level)


def test_page_is_cross_origin_isolated_and_serves_pyodide(ide):
    assert ide.js("crossOriginIsolated") is True
    assert not [u for u in ide.requests if "pyodide" in u], "Pyodide loads with a block program open"
    kinds = ide.js("""async () => {
      const { version } = await import('/vendor/pyodide/pyodide.mjs');
      const out = { version };
      for (const f of ['pyodide.asm.wasm', 'python_stdlib.zip', 'pyodide-lock.json', 'pyodide.asm.mjs', '../pyodide.mjs']) {
        const r = await fetch(`/vendor/pyodide/${version}/${f}`);
        out[f] = [r.status, r.headers.get('content-type'), r.headers.get('content-encoding'), r.headers.get('cache-control')];
      }
      return out;
    }""")
    immutable = "public, max-age=31536000, immutable"     # a versioned path never changes
    assert kinds["pyodide.asm.wasm"] == [200, "application/wasm", "gzip", immutable]   # the build's gzip of it
    assert kinds["python_stdlib.zip"][0] == 200 and "zip" in kinds["python_stdlib.zip"][1]
    assert kinds["pyodide-lock.json"][0] == 200 and "json" in kinds["pyodide-lock.json"][1]
    assert kinds["pyodide.asm.mjs"][0] == 200 and "javascript" in kinds["pyodide.asm.mjs"][1]
    assert {k: v[3] for k, v in kinds.items() if isinstance(v, list) and k != "../pyodide.mjs"} == dict.fromkeys(
        ["pyodide.asm.wasm", "python_stdlib.zip", "pyodide-lock.json", "pyodide.asm.mjs"], immutable)
    # the loader names the version: it is revalidated at every load (a new install, a new version)
    assert kinds["../pyodide.mjs"][:2] == [200, "text/javascript"] and kinds["../pyodide.mjs"][3] == "no-cache"


def test_a_reload_starts_python_from_the_browsers_cache(chromium, turtle_gateway):
    """A second page of the same browser starts Pyodide without its files crossing the network again."""
    ctx = chromium.new_context()
    try:
        transferred = []
        for _ in range(2):
            page = ctx.new_page()
            page.goto(turtle_gateway.http_url)
            page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=30000)
            page.evaluate("async () => (await import('/js/run/pyrun.js')).prepare()")
            transferred.append(page.evaluate("async () => (await import('/js/run/pyrun.js')).startTiming().transferred"))
            page.close()
        first, again = transferred
        heavy = ("pyodide.asm.wasm", "python_stdlib.zip", "pyodide.asm.mjs")
        assert all(first[f] > 100_000 for f in heavy), first
        assert all(again[f] == 0 for f in heavy), again        # from the cache, not revalidated
    finally:
        ctx.close()


def test_sleep_drives_the_turtle_and_prints_reach_the_log(ide, turtle_ros):
    pose = turtle_ros.watch("/turtle1/pose", "turtlesim/msg/Pose")
    wait_for(pose.latest, what="a pose")
    x0 = pose.latest()["x"]
    # it drives until its own subscription sees the turtle 1 m on (a busy machine may starve a run
    # of fixed length), then stops
    start(ide, """import time
import roslibpy

ros = roslibpy.Ros(host='robot.example', port=9090)
ros.run()
cmd = roslibpy.Topic(ros, '/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
poses = []
roslibpy.Topic(ros, '/turtle1/pose', 'turtlesim/msg/Pose').subscribe(poses.append)
while not poses:
    time.sleep(0.05)
x0 = poses[-1]['x']
print('driving')
end = time.monotonic() + 60
i = 0
while poses[-1]['x'] < x0 + 1.0 and time.monotonic() < end:
    cmd.publish(roslibpy.Message({'linear': {'x': 2.0, 'y': 0.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}))
    time.sleep(0.1)
    i += 1
print('done', i > 0)
ros.terminate()
""")
    o = finish(ide, PYODIDE_START + 60)
    assert o["errors"] == []
    assert "driving" in logged(ide, "info") and "done True" in logged(ide, "info"), (o, ide.js("rosgateIde.link?.lastLost ?? null"))
    wait_for(lambda: pose.latest()["x"] > x0 + 1.0, what="the turtle moved forward")
    assert o["lines"], "the running line was reported"


def test_textbook_roslibpy_program_runs_unchanged(ide, turtle_ros):
    start(ide, """import time
import roslibpy

client = roslibpy.Ros(host='localhost', port=9090)
client.run()
print('connected', client.is_connected)

poses = []
listener = roslibpy.Topic(client, '/turtle1/pose', 'turtlesim/msg/Pose')
listener.subscribe(lambda message: poses.append(message))
while not poses:
    time.sleep(0.05)
print('pose x', round(poses[-1]['x'], 1))
listener.unsubscribe()

service = roslibpy.Service(client, '/rosapi/get_time', 'rosapi/srv/GetTime')
result = service.call(roslibpy.ServiceRequest())
print('time', 'time' in result)

teleport = roslibpy.Service(client, '/turtle1/teleport_absolute', 'turtlesim/srv/TeleportAbsolute')
teleport.call(roslibpy.ServiceRequest({'x': 3.0, 'y': 4.0, 'theta': 0.0}))

answers = []
service.call(roslibpy.ServiceRequest(), lambda r: answers.append(r))
while not answers:
    time.sleep(0.01)
print('callback answered')

action = roslibpy.ActionClient(client, '/fibonacci', 'example_interfaces/action/Fibonacci')
feedback = []
results = []
goal_id = action.send_goal(roslibpy.Goal({'order': 5}), lambda r: results.append(r),
                           lambda f: feedback.append(f), lambda e: print('error', e))
action.wait_goal(goal_id)
print('sequence', list(results[0]['values']['sequence']), 'feedbacks', len(feedback) > 0)
client.terminate()
""")
    o = finish(ide)
    assert o["errors"] == [], logged(ide)
    text = logged(ide, "info")
    assert "connected True" in text and "pose x" in text and "time True" in text
    assert "callback answered" in text
    assert "sequence [0, 1, 1, 2, 3, 5] feedbacks True" in text
    pose = turtle_ros.watch("/turtle1/pose", "turtlesim/msg/Pose")
    wait_for(lambda: (p := pose.latest()) and abs(p["x"] - 3.0) < 0.05 and abs(p["y"] - 4.0) < 0.05,
             what="the turtle teleported")


def test_stop_zeroes_the_turtle(ide, turtle_ros):
    cmd = turtle_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
    start_until(ide, PY_DRIVE, lambda: any(m["linear"]["x"] == 0.5 for _, m in cmd.messages), "the program drives")
    t0 = time.monotonic()
    ide.js("async () => (await import('/js/run/pyrun.js')).stopPython()")
    zero = wait_for(lambda: next((t for t, m in cmd.since(t0) if m["linear"]["x"] == 0 and m["angular"]["z"] == 0),
                                 None), what="a zero Twist")
    finish(ide, 10)
    time.sleep(0.3)   # nothing drives after the zero: the worker is gone
    assert all(m["linear"]["x"] == 0 for t, m in cmd.since(zero + 0.05))


def test_stop_ends_a_busy_loop(ide):
    start_until(ide, "print('spinning')\nwhile True:\n    pass\n", lambda: "spinning" in logged(ide), "it spins")
    ide.js("async () => (await import('/js/run/pyrun.js')).stopPython()")
    finish(ide, 10)   # a loop that never yields ends: Stop ends its worker (how soon: tests.bench stop)
    assert "spinning" in logged(ide)


def test_runtime_error_reports_the_students_line(ide):
    start(ide, """import roslibpy
ros = roslibpy.Ros('localhost', 9090)

def speed(v):
    return v / 0

print('before')
speed(3)
""")
    o = finish(ide)
    assert len(o["errors"]) == 1
    err = o["errors"][0]
    assert err["line"] == 5 and err["message"] == "ZeroDivisionError: division by zero"
    assert 'File "<program>", line 8' in err["traceback"] and 'File "<program>", line 5' in err["traceback"]
    assert "rosgate_browser" not in err["traceback"] and "pyodide" not in err["traceback"]
    assert "ZeroDivisionError" in logged(ide, "error")
    assert "before" in logged(ide, "info")


def test_rosgate_runtime_runs_in_the_page(ide, turtle_ros):
    """The runtime the downloaded scripts use, on the page's roslibpy: sleep, wait for a message,
    a service call and an action block; a handler runs while the program waits."""
    pose = turtle_ros.watch("/turtle1/pose", "turtlesim/msg/Pose")
    wait_for(pose.latest, what="a pose")
    start(ide, """import rosgate_runtime as r

def main():
    rt = r.rt
    seen = []
    rt.on_message('/turtle1/pose', 'turtlesim/msg/Pose', lambda m: seen.append(m['x']))
    rt.call_service('/turtle1/teleport_absolute', 'turtlesim/srv/TeleportAbsolute', {'x': 5.0, 'y': 5.0, 'theta': 0.0})
    m = rt.wait_for_message('/turtle1/pose', 'turtlesim/msg/Pose', 5)
    rt.log('pose %.1f' % m['y'])
    rt.drive('/turtle1/cmd_vel', 'geometry_msgs/msg/Twist', {'linear': {'x': 1.0, 'y': 0.0, 'z': 0.0},
             'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}, 0.5)
    seq = rt.send_goal('/fibonacci', 'example_interfaces/action/Fibonacci', {'order': 4})
    rt.log(seq['sequence'])
    rt.log('handled %s' % (len(seen) > 0))
    rt.sleep(0.2)
    raise SystemExit(0)

r.run(main)
""")
    o = finish(ide)
    assert o["errors"] == [], logged(ide)
    text = logged(ide, "info")
    assert "pose 5.0" in text and "[0, 1, 1, 2, 3]" in text and "handled True" in text
    wait_for(lambda: pose.latest()["x"] > 5.05, what="the turtle drove")


def test_check_python_finds_a_syntax_error(ide):
    errors = ide.js("""async () => (await import('/js/run/pyrun.js')).checkPython('x = 1\\nif x > 0\\n    print(x)\\n')""")
    assert len(errors) == 1 and errors[0]["line"] == 2 and "SyntaxError" in errors[0]["message"]
    assert ide.js("async () => (await import('/js/run/pyrun.js')).checkPython('print(1)\\n')") == []
