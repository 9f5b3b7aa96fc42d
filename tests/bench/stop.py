"""How soon Stop stops the turtle: from the Stop in the IDE page to the zero Twist on /turtle1/cmd_vel,
as an independent roslibpy client receives it, in Chromium on `--robot turtlesim`:

    python -m tests.bench stop [--repeat 10] [--out stop.json]

* **blocks**: a block program drives; the Stop button is clicked (the page notes the click's time);
* **python**: a Python program in the page (Pyodide, ide/js/run/pyrun.js) publishes at 20 Hz; the page
  calls stopPython() (and notes the time it did);
* **killed**: a teleop process (tests/security/teleop.py) streams at 50 Hz and is killed (SIGKILL):
  from the kill to the zero the gateway publishes for the dropped connection.

Both ends read the same wall clock (one machine), so the figure is click to arrival, without the
test driver's own round trips. The bars: 300 ms for blocks, 500 ms for Python, 200 ms for a kill.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import threading
import time

from tests.bench.pyodide import RUN, open_ide
from tests.bench.report import save
from tests.support.ide import CHROMIUM, CHROMIUM_ARGS, PY_DRIVE, drive, program
from tests.support.process import GatewayProcess
from tests.support.wait import wait_for

NOTE_CLICK = """() => document.querySelector('#stop').addEventListener('click',
  () => { window.stopClickedAt = performance.timeOrigin + performance.now(); }, {capture: true, once: true})"""
STOP_PYTHON = """async () => {
  const py = await import('/js/run/pyrun.js');
  const at = performance.timeOrigin + performance.now();
  py.stopPython();
  return at;
}"""
BARS = {"blocks": 300.0, "python": 500.0, "killed": 200.0}


class Twists:
    """/turtle1/cmd_vel with wall-clock arrival times."""

    def __init__(self, gw):
        import roslibpy
        self.ros = roslibpy.Ros(gw.host, gw.port)
        self.ros.run(timeout=10)
        self.items: list[tuple[float, dict]] = []
        self.lock = threading.Lock()
        self.topic = roslibpy.Topic(self.ros, '/turtle1/cmd_vel', 'geometry_msgs/msg/Twist', queue_length=0)
        self.topic.subscribe(self._on)

    def _on(self, msg):
        with self.lock:
            self.items.append((time.time(), msg))

    def moving_since(self, t: float) -> bool:
        with self.lock:
            return any(at >= t and m["linear"]["x"] != 0 for at, m in self.items)

    def zero_after(self, t: float):
        with self.lock:
            return next((at for at, m in self.items if at >= t and m["linear"]["x"] == 0
                         and m["angular"]["z"] == 0), None)

    def close(self):
        self.ros.close()   # and with it the subscription


def blocks_once(page, twists: Twists) -> float:
    page.evaluate("(p) => rosgateIde.loadProgram(p)", program(drive(60)))
    t = time.time()
    page.click("#run")
    wait_for(lambda: twists.moving_since(t), timeout=30, what="the program driving")
    page.evaluate(NOTE_CLICK)
    page.click("#stop")
    clicked = page.evaluate("window.stopClickedAt") / 1000
    zero = wait_for(lambda: twists.zero_after(clicked), timeout=10, what="the zero after Stop")
    page.wait_for_function("document.body.dataset.run === 'idle'")
    return 1000 * (zero - clicked)


def python_once(page, twists: Twists) -> float:
    t = time.time()
    page.evaluate(RUN, {"source": PY_DRIVE, "ns": ""})
    wait_for(lambda: twists.moving_since(t), timeout=120, what="the Python program driving")
    asked = page.evaluate(STOP_PYTHON) / 1000
    zero = wait_for(lambda: twists.zero_after(asked), timeout=10, what="the zero after stopPython()")
    page.wait_for_function("window.pyOut.done")
    return 1000 * (zero - asked)


def killed_once(gw, twists: Twists) -> float:
    proc = subprocess.Popen([sys.executable, "-m", "tests.security.teleop", gw.ws_url, "/turtle1/cmd_vel", "50"],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "streaming"
        t = time.time()
        wait_for(lambda: twists.moving_since(t), what="the teleop process driving")
        killed = time.time()
        os.kill(proc.pid, signal.SIGKILL)
        zero = wait_for(lambda: twists.zero_after(killed), what="the zero after the kill")
    finally:
        proc.kill()
        proc.wait()
    return 1000 * (zero - killed)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=10)
    parser.add_argument("--out", help="the figures as JSON")
    args = parser.parse_args(argv)
    from playwright.sync_api import sync_playwright
    gw = GatewayProcess("--robot", "turtlesim")
    twists = Twists(gw)
    figures: dict = {"blocks": [], "python": [], "killed": []}
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            page = open_ide(browser.new_context(), gw)
            for _ in range(args.repeat):
                figures["blocks"].append(blocks_once(page, twists))
                figures["python"].append(python_once(page, twists))
                figures["killed"].append(killed_once(gw, twists))
            browser.close()
    finally:
        twists.close()
        gw.stop()
    missed = 0
    for kind, ms in figures.items():
        ms.sort()
        worst = ms[-1]
        missed += worst > BARS[kind]
        print(f"stop {kind:7}: to the zero at the robot, median {statistics.median(ms):.0f} ms, "
              f"max {worst:.0f} ms over {len(ms)} (bar {BARS[kind]:.0f} ms)")
    save(args.out, figures)
    return 1 if missed else 0
