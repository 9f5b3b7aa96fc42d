"""Python in the IDE page (Pyodide in a worker, ide/js/run/pyrun.js), in Chromium, on `--robot turtlesim`:

    python -m tests.bench pyodide [--repeat 3] [--seconds 3] [--out pyodide.json]

* **start**: from runPython() to the program's first print, in a fresh page of a fresh browser
  context (cold: an empty cache) and in a fresh page of the same context (warm: Pyodide's versioned
  files and the WebAssembly compiled from them in the browser's cache); the bytes the gateway sent
  for it (bodies and headers of every response from runPython on, Playwright's request sizes); the
  worker's phases (Pyodide loaded, our modules in, ready); against the goals (GOALS: warm <= 3 s,
  cold <= 10 s to the first print on a 2-core machine), with the load average beside;
* **open**: a page opened on a new Python text program (`?mode=text&lang=python`, warm): from the
  page's start to "Python ready" in the editor's bar (Pyodide starts when a Python program opens,
  so a Run after that many seconds prints at once);
* **memory**: the worker's while a program sleeps (Python's wasm heap, the worker's JavaScript
  heap where Chromium tells it), and the page's own beside it;
* **rate**: commands a loop publishes for ``--seconds`` s (std_msgs/Int32 on /bench/count,
  counted by an independent roslibpy client): Python with roslibpy's Topic.publish, Python with the
  runtime's rt.publish, Python with rclpy (a node's publisher; the page's rclpy), and the block
  programs' JavaScript runtime (Runtime.publish, with its loop trap tick()), in the same page.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import threading
import time

from tests.bench.report import save
from tests.support import page_state
from tests.support.ide import CHROMIUM, CHROMIUM_ARGS
from tests.support.process import GatewayProcess

RUN = """async ({source, ns}) => {
  const py = await import('/js/run/pyrun.js');
  const out = window.pyOut = {logs: [], errors: [], done: false, t0: performance.now()};
  py.runPython(source, {ros: rosgateIde.ros, namespace: ns,
    log: (text, level) => { out.logs.push([performance.now(), level, text]); },
    onError: (e) => out.errors.push(e)}).then(() => { out.done = true; });
}"""
FIRST_PRINT = "print('up')\n"
SLEEPER = "import _rosgate_js, time\nprint('memory', _rosgate_js.memory())\nprint('up')\nwhile True:\n    time.sleep(0.1)\n"
PY_LOOP = """import time, roslibpy
ros = roslibpy.Ros('localhost', 9090)
ros.run()
topic = roslibpy.Topic(ros, '/bench/count', 'std_msgs/msg/Int32')
topic.advertise()
time.sleep(0.5)
n, end = 0, time.monotonic() + {seconds}
while time.monotonic() < end:
    n += 1
    topic.publish(roslibpy.Message({{'data': n}}))
print('sent', n)
time.sleep(0.5)
ros.terminate()
"""
PY_RUNTIME_LOOP = """import time
import rosgate_runtime as r

def main():
    r.rt.sleep(0.5)
    n, end = 0, time.monotonic() + {seconds}
    while time.monotonic() < end:
        n += 1
        r.rt.publish('/bench/count', 'std_msgs/msg/Int32', {{'data': n}})
    print('sent', n)
    r.rt.sleep(0.5)
    raise SystemExit(0)

r.run(main)
"""
PY_RCLPY_LOOP = """import time
import rclpy
from rclpy.node import Node
from std_msgs.msg import Int32

rclpy.init()
node = Node('bench_loop')
pub = node.create_publisher(Int32, '/bench/count', 10)
time.sleep(0.5)
n, end = 0, time.monotonic() + {seconds}
msg = Int32()
while time.monotonic() < end:
    n += 1
    msg.data = n
    pub.publish(msg)
print('sent', n)
time.sleep(0.5)
node.destroy_node()
rclpy.shutdown()
"""
GOALS = {"cold": 10000, "warm": 3000}   # ms from Run to the first print, on a 2-core machine
JS_LOOP = """async (seconds) => {
  const { Runtime } = await import('/runtime/runtime.js');
  const rt = new Runtime(rosgateIde.ros, {});
  rt.advertise('/bench/count', 'std_msgs/msg/Int32');
  await rt.sleep(0.5);
  let n = 0;
  const end = performance.now() + seconds * 1000;
  while (performance.now() < end) {
    n += 1;
    rt.publish('/bench/count', 'std_msgs/msg/Int32', {data: n});
    await rt.tick();
  }
  await rt.sleep(0.5);
  rt.stop();
  return n;
}"""


class Counter:
    """Messages on /bench/count, as an independent roslibpy client receives them."""

    def __init__(self, gw):
        import roslibpy
        self.ros = roslibpy.Ros(gw.host, gw.port)
        self.ros.run(timeout=10)
        self.n = 0
        self.lock = threading.Lock()
        self.topic = roslibpy.Topic(self.ros, '/bench/count', 'std_msgs/msg/Int32', queue_length=0)
        self.topic.subscribe(self._on)

    def _on(self, _msg):
        with self.lock:
            self.n += 1

    def take(self) -> int:
        with self.lock:
            n, self.n = self.n, 0
        return n

    def close(self):
        self.topic.unsubscribe()
        self.ros.close()


def open_ide(ctx, gw):
    page = page_state.install(ctx.new_page())
    page.goto(gw.http_url)
    page.wait_for_function("document.body?.dataset.ready === 'true' && document.body.dataset.connection === 'connected'",
                           timeout=30000)
    return page


def run_py(page, source: str):
    page.evaluate(RUN, {"source": source, "ns": ""})


def wait_up(page, timeout: float = 120) -> float:
    """ms from runPython to the first print."""
    page.wait_for_function("window.pyOut.logs.some(([, , t]) => t === 'up') || window.pyOut.errors.length",
                           timeout=timeout * 1000)
    out = page.evaluate("window.pyOut")
    if out["errors"]:
        raise RuntimeError(out["errors"])
    return next(t for t, _, text in out["logs"] if text == "up") - out["t0"]


def stop(page):
    page.evaluate("async () => (await import('/js/run/pyrun.js')).stopPython()")


def start_once(ctx, gw) -> tuple[float, int, dict]:
    """(ms to the first print, bytes the gateway sent from runPython on, the worker's phases) in a
    fresh page of ctx."""
    page = open_ide(ctx, gw)
    requests: list = []

    def take(request):
        requests.append(request)
    page.on("requestfinished", take)
    run_py(page, FIRST_PRINT)
    ms = wait_up(page)
    page.remove_listener("requestfinished", take)   # the spare worker for a next run loads next
    sent = sum(s["responseBodySize"] + s["responseHeadersSize"] for s in (r.sizes() for r in requests))
    phases = page.evaluate("async () => (await import('/js/run/pyrun.js')).startTiming()") or {}
    page.close()
    return ms, sent, phases


def open_text(ctx, gw) -> float:
    """ms from a page's start (its navigation) to Python ready in the bar of a new Python program."""
    page = page_state.install(ctx.new_page())
    page.goto(gw.http_url + "?mode=text&lang=python")
    page.wait_for_selector(".text-python[data-state='ready']", timeout=120000)
    ms = page.evaluate("performance.now()")
    page.close()
    return ms


def memory(page) -> dict:
    """Bytes of the worker (Python's wasm heap, its JavaScript heap) while a program sleeps, and the
    page's own (performance.measureUserAgentSpecificMemory(): the page is cross-origin isolated;
    Chromium leaves the worker out of its breakdown)."""
    run_py(page, SLEEPER)
    wait_up(page)
    worker = json.loads(next(t for _, _, t in page.evaluate("window.pyOut.logs") if t.startswith("memory"))[7:])
    m = page.evaluate("performance.measureUserAgentSpecificMemory()")
    stop(page)
    return {"worker wasm": worker["wasm"], "worker js": worker["js"], "page": m["bytes"]}


def rate(page, counter: Counter, seconds: float) -> dict:
    out = {}
    for name, source in (("python roslibpy", PY_LOOP), ("python runtime", PY_RUNTIME_LOOP), ("python rclpy", PY_RCLPY_LOOP)):
        counter.take()
        run_py(page, source.format(seconds=seconds))
        page.wait_for_function("window.pyOut.done", timeout=(seconds + 120) * 1000)
        o = page.evaluate("window.pyOut")
        if o["errors"]:
            raise RuntimeError(o["errors"])
        said = next((t for _, _, t in o["logs"] if t.startswith("sent")), None)
        if said is None:     # the run ended early (the page's link dropped on a loaded machine ...)
            print(f"rate {name}: no count; the run said {[t for _, _, t in o['logs']][-5:]}")
            continue
        sent = int(said.split()[1])
        out[name] = {"sent": sent / seconds, "received": counter.take() / seconds}
    counter.take()
    sent = page.evaluate(JS_LOOP, seconds)
    time.sleep(0.5)
    out["javascript runtime"] = {"sent": sent / seconds, "received": counter.take() / seconds}
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--out", help="the figures as JSON")
    args = parser.parse_args(argv)
    from playwright.sync_api import sync_playwright
    gw = GatewayProcess("--robot", "turtlesim")
    counter = Counter(gw)
    figures: dict = {"cold": [], "warm": [], "open": [], "load": [os.getloadavg()[0]]}
    try:
        with sync_playwright() as p:
            for i in range(args.repeat):
                # a profile on disk, as a student's browser has: an incognito context keeps no 10 MB file
                with tempfile.TemporaryDirectory(prefix="rosgate-bench-profile-") as profile:
                    ctx = p.chromium.launch_persistent_context(
                        profile, executable_path=CHROMIUM,
                        args=CHROMIUM_ARGS + ["--enable-blink-features=ForceEagerMeasureMemory"])
                    figures["cold"].append(start_once(ctx, gw))
                    figures["warm"].append(start_once(ctx, gw))
                    figures["open"].append(open_text(ctx, gw))
                    if i == args.repeat - 1:
                        page = open_ide(ctx, gw)
                        figures["memory"] = memory(page)
                        figures["rate"] = rate(page, counter, args.seconds)
                    ctx.close()
    finally:
        counter.close()
        gw.stop()
    figures["load"].append(os.getloadavg()[0])
    load = "load average %.1f at the start, %.1f at the end (2 cores)" % tuple(figures["load"])
    for kind in ("cold", "warm"):
        ms = [m for m, _, _ in figures[kind]]
        sent = [b for _, b, _ in figures[kind]]
        phases = [p for _, _, p in figures[kind] if p]
        goal = GOALS[kind]
        print(f"start {kind}: runPython -> first print median {statistics.median(ms):.0f} ms "
              f"({' '.join(f'{m:.0f}' for m in ms)}); goal <= {goal} ms: "
              f"{'met' if statistics.median(ms) <= goal else 'NOT met'}; sent {statistics.median(sent) / 1e3:.0f} kB")
        if phases:
            print("  worker (median ms from its start): " + ", ".join(
                f"{k} {statistics.median(p[k] for p in phases):.0f}" for k in ("pyodide", "files", "ready")))
    print(f"open a Python program (warm): page start -> Python ready median {statistics.median(figures['open']):.0f} ms "
          f"({' '.join(f'{m:.0f}' for m in figures['open'])})")
    print(load)
    mem = figures["memory"]
    js_heap = "?" if mem["worker js"] is None else "%.1f" % (mem["worker js"] / 1e6)
    print(f"memory: worker {mem['worker wasm'] / 1e6:.1f} MB wasm + {js_heap} MB JavaScript heap; "
          f"the page itself {mem['page'] / 1e6:.1f} MB")
    for name, r in figures["rate"].items():
        print(f"rate {name:20}: {r['sent']:8.0f} commands/s sent, {r['received']:8.0f}/s received")
    save(args.out, figures)
    return 0
