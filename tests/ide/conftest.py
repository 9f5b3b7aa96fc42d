"""Browser fixtures: Debian's Chromium driven by Playwright, pages of the IDE and the teleop page,
and independent roslibpy clients that watch what the robots do."""

from __future__ import annotations

import json
import os
import shutil
import threading
import time
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(__file__).resolve().parent / "artifacts"
EXAMPLES = ROOT / "examples"
CHROMIUM = os.environ.get("ROSGATE_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
TABLET, PHONE = {"width": 1180, "height": 820}, {"width": 390, "height": 844}   # viewports
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--no-first-run", "--disable-sync"]


def pytest_collection_modifyitems(items):
    for item in items:
        if "tests/ide/" in str(item.fspath).replace(os.sep, "/"):
            item.add_marker(pytest.mark.timeout(180))


@pytest.fixture(scope="module")
def chromium():
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Chromium not found at {CHROMIUM}: apt-get install chromium")
    if not (ROOT / "ide" / "vendor" / "roslib.mjs").exists():
        pytest.fail("the IDE's vendor/ is not built: cd ide && npm ci && npm run build")
    from playwright.sync_api import sync_playwright
    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield browser
        browser.close()


class Watch:
    """Records every message of a topic with its arrival time (an independent roslibpy client)."""

    def __init__(self, ros, topic: str, type_: str):
        import roslibpy
        self.messages: list[tuple[float, dict]] = []
        self.lock = threading.Lock()
        self.topic = roslibpy.Topic(ros, topic, type_)
        self.topic.subscribe(self._on)

    def _on(self, msg):
        with self.lock:
            self.messages.append((time.monotonic(), dict(msg)))

    def latest(self):
        with self.lock:
            return self.messages[-1][1] if self.messages else None

    def since(self, t0: float) -> list[tuple[float, dict]]:
        with self.lock:
            return [(t, m) for t, m in self.messages if t >= t0]

    def close(self):
        self.topic.unsubscribe()


def wait_for(predicate, timeout: float = 10.0, interval: float = 0.02, what: str = "condition"):
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"{what} not met within {timeout} s")
        time.sleep(interval)


class RosClient:
    """A roslibpy connection with helpers used to check robots independently of the browser."""

    def __init__(self, gateway):
        import roslibpy
        self.roslibpy = roslibpy
        self.ros = roslibpy.Ros(gateway.host, gateway.port)
        self.ros.run(timeout=10)
        self.watches: list[Watch] = []

    def watch(self, topic: str, type_: str) -> Watch:
        w = Watch(self.ros, topic, type_)
        self.watches.append(w)
        return w

    def call(self, service: str, type_: str, args: dict | None = None, timeout: float = 10):
        srv = self.roslibpy.Service(self.ros, service, type_)
        return srv.call(self.roslibpy.ServiceRequest(args or {}), timeout=timeout)

    def close(self):
        for w in self.watches:
            try:
                w.close()
            except Exception:
                pass
        self.ros.close()


class IdePage:
    """The block IDE in a browser page."""

    def __init__(self, page, gateway):
        self.page = page
        self.gateway = gateway
        self.errors: list[str] = []
        self.requests: list[str] = []
        page.on("request", lambda r: self.requests.append(r.url))
        page.on("pageerror", lambda e: self.errors.append(str(e)))
        page.on("console", lambda m: m.type == "error" and self.errors.append(m.text))

    def open(self, url: str | None = None):
        self.page.goto(url or self.gateway.http_url)
        self.page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=20000)
        self.page.wait_for_function("document.body?.dataset.connection === 'connected'", timeout=10000)
        return self

    def js(self, expr: str, arg=None):
        return self.page.evaluate(expr, arg)

    def load_example(self, file: str):
        program = json.loads((EXAMPLES / file).read_text())
        self.js("(p) => rosgateIde.loadProgram(p)", program)
        return program

    def make_block(self, kind: str, rosname: str, label: str, block_type: str):
        """"Make a block" through its dialog; returns once Blockly knows the new block type."""
        self.js("rosgateIde.makeBlock.open()")
        self.page.select_option("#dlg-make [name=kind]", kind)
        self.page.fill("#dlg-make [name=rosname]", rosname)
        self.page.fill("#dlg-make [name=label]", label)
        self.page.click("#dlg-make [data-act=create]")
        self.page.wait_for_function("(t) => !!Blockly.Blocks[t]", arg=block_type)

    def workspace(self) -> dict:
        return self.js("Blockly.serialization.workspaces.save(rosgateIde.workspace)")

    def python(self) -> str:
        return self.js("rosgateIde.generatePython()")

    def javascript(self) -> str:
        return self.js("rosgateIde.generateJs(false)")

    def run(self):
        runs = self.js("rosgateIde.runner.runs")
        self.page.click("#run")
        self.page.wait_for_function(f"rosgateIde.runner.runs > {runs}", timeout=5000)

    def wait_idle(self, timeout: float = 60):
        self.page.wait_for_function("document.body?.dataset.run === 'idle'", timeout=timeout * 1000)

    def logs(self) -> list[str]:
        return self.js("rosgateIde.console.logs()")

    def console_text(self) -> str:
        return self.page.inner_text("#console-lines")

    def screenshot(self, name: str):
        self.page.screenshot(path=str(ARTIFACTS / f"{name}.png"))


def open_teleop(chromium, gw, query: str = "", **ctx_args):
    """The teleop page (with ``query``) in a new browser context, ready and connected:
    (context, page, its page errors)."""
    ctx = chromium.new_context(**ctx_args)
    page = ctx.new_page()
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(gw.http_url + "teleop" + query)
    page.wait_for_function("document.body?.dataset.ready === 'true'")
    page.wait_for_function("document.body?.dataset.connection === 'connected'")
    return ctx, page, errors


@pytest.fixture
def ide_factory(chromium):
    contexts = []

    def make(gateway, url: str | None = None, **context_args) -> IdePage:
        ctx = chromium.new_context(**{"viewport": {"width": 1400, "height": 860}, **context_args})
        contexts.append(ctx)
        return IdePage(ctx.new_page(), gateway).open(url)

    yield make
    for ctx in contexts:
        ctx.close()


@pytest.fixture(scope="module")
def turtle_gateway(start_gateway):
    return start_gateway("--robot", "turtlesim", "--fibonacci-interval", "0.05")


@pytest.fixture(scope="module")
def rover_gateway(start_gateway):
    return start_gateway("--robot", "rover", "--fibonacci-interval", "0.05")


@pytest.fixture
def turtle_ros(turtle_gateway):
    client = RosClient(turtle_gateway)
    yield client
    client.close()


@pytest.fixture
def rover_ros(rover_gateway):
    client = RosClient(rover_gateway)
    yield client
    client.close()


@pytest.fixture
def rover():
    """A fresh rover gateway of its own (the test may change the rover's state) and a client for it."""
    from tests.conftest import GatewayProcess
    gw = GatewayProcess("--robot", "rover")
    client = RosClient(gw)
    yield gw, client
    client.close()
    gw.stop()


@pytest.fixture(scope="module")
def py_runtime():
    """The Python runtime that generated programs carry, loaded as a module."""
    module = types.ModuleType("rosgate_runtime")
    exec(compile((ROOT / "ide/runtime/rosgate_runtime.py").read_text(), "rosgate_runtime.py", "exec"),
         module.__dict__)
    return module


@pytest.fixture(scope="module")
def util_page(chromium, start_gateway):
    """A page on the gateway's origin that can import /runtime/util.js (no IDE start-up needed)."""
    gw = start_gateway()
    ctx = chromium.new_context()
    page = ctx.new_page()
    page.goto(gw.http_url + "runtime/util.js")
    yield page
    ctx.close()
