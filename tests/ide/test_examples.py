"""Every example: run from the IDE's Run button in Chromium, then its generated Python as a
subprocess against the same sim; an independent roslibpy client checks the robot's result
both times, and both runs must log the same lines."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time

import pytest

from tests.support.ide import ARTIFACTS
from tests.support.ros import LOOP_HEADING as HEADING, LOOP_REACH as REACH, START, reset_turtlesim
from tests.support.wait import wait_for



def run_python(ide, gateway, name: str, stop_when=None, timeout: float = 90):
    """Runs the IDE's generated Python against the gateway; returns (stdout lines, stderr).

    With ``stop_when`` (a condition), the program gets Ctrl-C once the condition holds."""
    path = ARTIFACTS / f"{name}.py"
    path.write_text(ide.python())
    proc = subprocess.Popen([sys.executable, str(path), "--url", gateway.ws_url],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        if stop_when is not None:
            wait_for(lambda: stop_when() or proc.poll() is not None, timeout=timeout,
                     what=f"{name}.py reaching its stop condition")
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, f"{name}.py exited {proc.returncode}\n{err}"
    return out.splitlines(), err


def run_in_ide(ide, timeout: float = 60):
    ide.run()
    ide.wait_idle(timeout)
    text = ide.console_text()
    assert "finished" in text, text
    return ide.logs()


def angle_close(a: float, b: float, tol: float) -> bool:
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi) < tol


# ---- turtlesim ------------------------------------------------------------------
def check_square(ros, pose, cmd):
    p = pose.latest()
    assert abs(p["x"] - START) < 2 * REACH and abs(p["y"] - START) < 2 * REACH, p
    assert angle_close(p["theta"], 0, 2 * HEADING), p
    # the turtle went round: it was at the far corner at some point
    assert any(abs(m["x"] - (START + 3)) < REACH and abs(m["y"] - (START + 3)) < REACH for _, m in pose.messages)
    # the pen drew in yellow under the turtle (turtlesim's colour sensor reads the pixel below it)
    colour = ros.watch("/turtle1/color_sensor", "turtlesim/msg/Color")
    c = wait_for(colour.latest, what="a colour sensor reading")
    assert (c["r"], c["g"], c["b"]) == (255, 220, 0), c
    wait_for(lambda: cmd.latest()["linear"]["x"] == 0 and cmd.latest()["angular"]["z"] == 0, timeout=30,
             what="the zero as the last command")   # on this other connection a moment after the run's end


def expected_spiral():
    x = y = START
    th = 0.0
    for i in range(1, 9):
        x += 0.4 * i * math.cos(th)
        y += 0.4 * i * math.sin(th)
        th += math.radians(60)
    return x, y, th


def check_spiral(ros, pose, cmd):
    x, y, th = expected_spiral()
    p = pose.latest()
    assert abs(p["x"] - x) < 2 * REACH and abs(p["y"] - y) < 2 * REACH, (p, x, y)
    assert angle_close(p["theta"], th, HEADING), (p, th)


def check_three(ros, pose, cmd):
    for i, name in enumerate(("turtle2", "turtle3", "turtle4"), start=1):
        w = ros.watch(f"/{name}/pose", "turtlesim/msg/Pose")
        p = wait_for(w.latest, what=f"{name} pose")
        assert abs(p["x"] - 2.5 * i) < 1e-6 and abs(p["y"] - 5.0) < REACH, (name, p)   # north: x stays
        assert angle_close(p["theta"], math.pi / 2, 0.01), (name, p)


TURTLE_EXAMPLES = {
    "drive_square.json": (check_square, ["square done"]),
    "spiral.json": (check_spiral, None),
    "three_turtles.json": (check_three, ["turtle2", "turtle3", "turtle4"]),
}


@pytest.mark.parametrize("file", list(TURTLE_EXAMPLES))
def test_turtlesim_example(file, turtle_gateway, turtle_ros, ide_factory):
    check, logs = TURTLE_EXAMPLES[file]
    ide = ide_factory(turtle_gateway)
    ide.load_example(file)
    name = file.removesuffix(".json")

    pose = reset_turtlesim(turtle_ros)
    cmd = turtle_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
    t0 = time.monotonic()
    js_logs = run_in_ide(ide)
    js_seconds = time.monotonic() - t0
    check(turtle_ros, pose, cmd)
    if logs is not None:
        assert js_logs == logs
    ide.page.wait_for_function("Object.keys(rosgateIde.world.summary()).includes('pen')")
    ide.screenshot(f"example-{name}")

    pose = reset_turtlesim(turtle_ros)
    t0 = time.monotonic()
    py_logs, _ = run_python(ide, turtle_gateway, name)
    py_seconds = time.monotonic() - t0
    check(turtle_ros, pose, cmd)
    assert py_logs == js_logs
    print(f"{file}: JavaScript {js_seconds:.1f} s, Python {py_seconds:.1f} s")
    assert not ide.errors, ide.errors


# ---- the demo action --------------------------------------------------------------------
def test_fibonacci_example(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.load_example("fibonacci.json")
    js_logs = run_in_ide(ide)
    fib = [0, 1, 1, 2, 3, 5, 8, 13, 21]
    assert js_logs[0] == "asking /fibonacci for order 8"
    assert js_logs[-2:] == ["result:", str(fib)]
    feedback = js_logs[1:-2]
    assert feedback, js_logs
    for line in feedback:               # every feedback is a growing prefix of the result
        seq = eval(line)                 # noqa: S307 - a list literal printed by the program
        assert seq == fib[:len(seq)]
    assert [len(eval(line)) for line in feedback] == sorted(len(eval(line)) for line in feedback)
    py_logs, _ = run_python(ide, turtle_gateway, "fibonacci")
    assert py_logs == js_logs


# ---- rover ---------------------------------------------------------------------------------
def odom_xy(msg):
    p = msg["pose"]["pose"]["position"]
    return p["x"], p["y"]


def travelled(watch, t0):
    pts = [odom_xy(m) for t, m in watch.since(t0)]
    return sum(math.dist(a, b) for a, b in zip(pts, pts[1:]))


def rover_at_rest(watch):
    m = watch.latest()
    return m and abs(m["twist"]["twist"]["linear"]["x"]) < 1e-3 and abs(m["twist"]["twist"]["angular"]["z"]) < 1e-3


@pytest.fixture
def fresh_rover():
    """A new rover world for each run, so both languages start from the same pose."""
    from tests.support.process import GatewayProcess
    started = []

    def start():
        gw = GatewayProcess("--robot", "rover")
        started.append(gw)
        return gw

    yield start
    for gw in started:
        gw.stop()


def test_rover_wall_follower(fresh_rover, ide_factory):
    from tests.support.ros import RosClient
    for language in ("javascript", "python"):
        gw = fresh_rover()
        ros = RosClient(gw)
        try:
            odom = ros.watch("/odom", "nav_msgs/msg/Odometry")
            bumper = ros.watch("/bumper", "std_msgs/msg/Bool")
            wait_for(odom.latest, what="odometry")
            t0 = time.monotonic()
            if language == "javascript":
                ide = ide_factory(gw)
                ide.load_example("wall_follower.json")
                ide.run()
                wait_for(lambda: travelled(odom, t0) > 2.0, timeout=20, what="the rover driving 2 m")
                ide.page.click("#stop")
                wait_for(lambda: rover_at_rest(odom), timeout=3, what="the rover stopping after Stop")
                assert ide.logs() == ["following the wall on the right"]
                ide.screenshot("example-wall_follower")
            else:
                out, _ = run_python(ide, gw, "wall_follower", stop_when=lambda: travelled(odom, t0) > 2.0)
                assert out == ["following the wall on the right"]
                assert travelled(odom, t0) > 2.0
                wait_for(lambda: rover_at_rest(odom), timeout=3, what="the rover stopping after Ctrl-C")
            assert not any(m["data"] for t, m in bumper.since(t0)), f"{language}: the rover hit something"
        finally:
            ros.close()


def test_rover_pid_go_to_goal(fresh_rover, ide_factory):
    from tests.support.ros import RosClient
    goal = (4.0, 2.5)
    logs = {}
    for language in ("javascript", "python"):
        gw = fresh_rover()
        ros = RosClient(gw)
        try:
            odom = ros.watch("/odom", "nav_msgs/msg/Odometry")
            start = odom_xy(wait_for(odom.latest, what="odometry"))
            assert math.dist(start, goal) > 1.5
            if language == "javascript":
                ide = ide_factory(gw)
                ide.load_example("pid_goal.json")
                logs[language] = run_in_ide(ide, timeout=60)
                ide.screenshot("example-pid_goal")
            else:
                logs[language], _ = run_python(ide, gw, "pid_goal")
            wait_for(lambda: rover_at_rest(odom), timeout=3, what="the rover at rest at the goal")
            assert math.dist(odom_xy(odom.latest()), goal) < 0.15, (language, odom_xy(odom.latest()))
            assert logs[language] and logs[language][-1].startswith("arrived"), logs
        finally:
            ros.close()
