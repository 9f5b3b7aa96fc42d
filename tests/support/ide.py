"""The IDE and the teleop page in Debian's Chromium driven by Playwright: the browser's path and
flags, viewports, a page of the IDE, and programs built from the examples' block makers."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil

from tests.support.process import ROOT
from tests.support.wait import wait_for
from tests.support.wsclient import Client

ARTIFACTS = ROOT / "tests" / "ide" / "artifacts"
EXAMPLES = ROOT / "examples"
CHROMIUM = os.environ.get("ROSGATE_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
TABLET, PHONE = {"width": 1180, "height": 820}, {"width": 390, "height": 844}   # viewports
PATIENCE_MS = 90_000   # ms: how long a page's wait may take on a busy machine (a deadline, not a bar)
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--no-first-run", "--disable-sync"]


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
        self.page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=PATIENCE_MS)
        self.page.wait_for_function("document.body?.dataset.connection === 'connected'", timeout=PATIENCE_MS)
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
        self.page.wait_for_function(f"rosgateIde.runner.runs > {runs}", timeout=PATIENCE_MS)

    def wait_idle(self, timeout: float = 60):
        self.page.wait_for_function("document.body?.dataset.run === 'idle'", timeout=timeout * 1000)

    def logs(self) -> list[str]:
        return self.js("rosgateIde.console.logs()")

    def console_text(self) -> str:
        return self.page.inner_text("#console-lines")

    def screenshot(self, name: str):
        self.page.screenshot(path=str(ARTIFACTS / f"{name}.png"))

    def console_lines(self) -> str:
        """The console's lines as they were written (a line of the program may hold a newline)."""
        return self.js("[...document.querySelectorAll('#console-lines .line')].map((d) => d.textContent).join('\\n')")

    def logged(self, text: str, timeout: float) -> str:
        """Waits until ``text`` is in the console; a failure says where the page's Python run was."""
        try:
            wait_for(lambda: text in self.console_lines(), timeout, what=repr(text))
        except AssertionError as e:
            raise AssertionError(f'{e}; console:\n{self.console_lines()[-3000:]}\npage errors: {self.errors}\n'
                                 f'the page: {self.python_state()}') from e
        return self.console_lines()

    def python_state(self) -> dict:
        """Where the page's Python run is, for a failure's message: the run's phase (checking:
        Python's load and its check, graph, running), whether a worker waits ready, the last worker's start, the link."""
        return self.page.evaluate("""async () => {
          const py = await import(new URL('js/run/pyrun.js', location.href)).catch((e) => null);
          return { phase: rosgateIde.textRunner.run_?.phase ?? null, ready: py?.isReady() ?? null,
                   timing: py?.startTiming() ?? null, lost: rosgateIde.link?.lastLost ?? null,
                   connection: document.body.dataset.connection };
        }""")


def open_teleop(chromium, gw, query: str = "", sent: list | None = None, **ctx_args):
    """The teleop page (with ``query``) in a new browser context, ready and connected:
    (context, page, its page errors). ``sent``, if given, gathers every op the page sends (parsed),
    from its first connection on."""
    ctx = chromium.new_context(**ctx_args)
    page = ctx.new_page()
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    if sent is not None:
        page.on("websocket", lambda ws: ws.on("framesent", lambda f: sent.append(json.loads(f))
                                                if isinstance(f, str) and f.startswith("{") else None))
    page.goto(gw.http_url + "teleop" + query)
    page.wait_for_function("document.body?.dataset.ready === 'true' && !!window.teleop")   # its state readable
    page.wait_for_function("document.body?.dataset.connection === 'connected'")
    return ctx, page, errors


def teleop_ready(page, ns: str | None = None, stations: str = r"^\/s0[1-3]$") -> str:
    """The teleop page's station (its #ns) once, in one look, it is ready, connected, on a station
    (``ns`` if given) and not about to reload into the station it has just claimed (the page marks
    that moment: body.dataset.reloading)."""
    found = page.wait_for_function("([want, pattern]) => { const b = document.body?.dataset ?? {};"
                                   " const v = document.querySelector('#ns')?.value;"
                                   " return b.ready === 'true' && b.connection === 'connected' && b.reloading !== 'true'"
                                   " && new RegExp(pattern).test(v) && (!want || v === want) ? v : null; }",
                                   arg=[ns, stations], timeout=40000)
    return found.json_value()


def drives_its_station(page, gw, token: str, ns: str) -> None:
    """Arrow-up on the teleop page reaches its station's turtle, as a client signed in with
    ``token`` watching ``ns``'s cmd_vel sees."""
    teleop_ready(page, ns)
    with Client(gw.ws_url, token) as watcher:
        watcher.subscribe(f'{ns}/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
        page.locator('body').click(position={'x': 5, 'y': 5})
        page.keyboard.down('ArrowUp')
        try:
            msg = watcher.expect(lambda m: m.get('op') == 'publish' and m['msg']['linear']['x'] > 0, timeout=30)
        except AssertionError as e:   # what the page did and what the gateway said, for the next person
            seen = page.evaluate("({published: teleop.published, blocked: teleop.blocked, keys: [...teleop.keys],"
                                 " focus: document.activeElement?.outerHTML.slice(0, 80), url: location.href,"
                                 " body: {...document.body.dataset}, notice: document.querySelector('#notice')?.innerText,"
                                 " lastLost: teleop.link?.lastLost ?? null})")
            log = [line for line in gw.log_text().splitlines() if 'WARNING' in line or 'dropped' in line][-10:]
            raise AssertionError(f'{e}; the page: {seen}; the gateway: {log}') from None
        page.keyboard.up('ArrowUp')
        assert msg['topic'] == f'{ns}/turtle1/cmd_vel'


_spec = importlib.util.spec_from_file_location("make_examples", EXAMPLES / "make_examples.py")
ex = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ex)


def program(*tops: dict, name: str = "test program", variables: dict | None = None) -> dict:
    blocks = [{**b, "x": 20, "y": 20 + 120 * i} for i, b in enumerate(tops)]
    return {"format": "rosgate-program", "version": 1, "name": name, "blocks": [],
            "workspace": {"blocks": {"languageVersion": 0, "blocks": blocks},
                          "variables": [{"name": n, "id": i} for n, i in (variables or {}).items()]}}


# A textbook roslibpy program that drives turtle1 in a circle at 20 Hz until it is stopped.
PY_DRIVE = """import time, roslibpy
ros = roslibpy.Ros('localhost', 9090)
ros.run()
cmd = roslibpy.Topic(ros, '/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
while True:
    cmd.publish({'linear': {'x': 0.5, 'y': 0.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': 1.0}})
    time.sleep(0.05)
"""


def drive(seconds: float = 30, speed: float = 1.0) -> dict:
    return ex.block("turtle_drive", inputs={"TURTLE": ex.text("turtle1"), "SPEED": ex.num(speed),
                                             "TURN": ex.num(0), "SECONDS": ex.num(seconds)})


def moving(w, t0=0.0):
    return any(m["linear"]["x"] != 0 for t, m in w.since(t0))


def bool_message() -> dict:
    return {"type": "ros_message", "extraState": {"kind": "msg", "type": "std_msgs/msg/Bool",
                                                  "fields": [{"name": "data", "type": "bool", "array": -1}]},
            "fields": {"TYPE": "std_msgs/msg/Bool"},
            "inputs": {"F_data": {"shadow": {"type": "logic_boolean", "fields": {"BOOL": "TRUE"}}}}}


# Text programs (the editor, CodeMirror's .cm-content)
def open_text(ide: IdePage, lang: str):
    """A new text program in `lang` (/?mode=text&lang=...), the robot's graph read."""
    ide.open(ide.gateway.http_url + f"?mode=text&lang={lang}")
    ide.page.wait_for_selector(".cm-content")
    ide.page.wait_for_function("rosgateIde.graph.loaded")
    assert ide.js("document.body.dataset.mode") == "text"
    assert ide.js("rosgateIde.textMode.lang") == lang


def page_errors(ide: IdePage) -> list[str]:
    """The page's errors but a send on a socket the link just dropped (a loaded machine's silence)."""
    return [e for e in ide.errors if "WebSocket is already in CLOSING or CLOSED state" not in e]


def error_line(ide: IdePage) -> int:
    """The line the editor marks as an error's (once it marks one)."""
    ide.page.wait_for_selector(".cm-error-line")
    return int(ide.page.get_attribute(".cm-error-line", "data-line"))
