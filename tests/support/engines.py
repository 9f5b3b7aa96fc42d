"""Three browser engines behind one small interface, for the pages' smoke suite (test_engines.py):
Chromium (Debian's, through Playwright, as the other browser tests), WebKitGTK (Debian's
WebKitWebDriver and its MiniBrowser under an Xvfb of its own, through Selenium, which is given the
driver's path so that Selenium Manager downloads nothing) and Firefox ESR (Debian's, through
puppeteer-core over WebDriver BiDi in tests/node/firefox-driver.mjs: Debian has no geckodriver).

An engine opens a page, evaluates JavaScript, waits for a condition (polled, with a deadline),
clicks and fills by selector, holds keys and drags a finger. Touch where the driver gives it:
Chromium (CDP touch events) and Firefox (BiDi touch actions) deliver real touch and pointer events;
WebKitWebDriver accepts a touch pointer but delivers it as the mouse (pointerType "mouse", no
touch events, navigator.maxTouchPoints 0: measured on WebKitGTK 2.50.6), so WebKit drags with the
mouse and says so (``touch = False``)."""

from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from tests.support.page_state import with_state

ROOT = Path(__file__).resolve().parents[2]
WEBKIT_DRIVER = os.environ.get("ROSGATE_WEBKIT_DRIVER") or "/usr/bin/WebKitWebDriver"
MINIBROWSER = os.environ.get("ROSGATE_MINIBROWSER") or "/usr/lib/x86_64-linux-gnu/webkit2gtk-4.1/MiniBrowser"
FIREFOX = os.environ.get("ROSGATE_FIREFOX") or shutil.which("firefox-esr") or "/usr/bin/firefox-esr"
FIREFOX_DRIVER = ROOT / "tests" / "node" / "firefox-driver.mjs"
SIZE = (1280, 860)
START = 120   # s: a browser's first start on a busy 2-core machine (Firefox makes its profile)


class Engine:
    name = ""
    touch = True      # does drag() deliver touch events (else the mouse)?

    def open(self, url: str) -> None:
        raise NotImplementedError

    def js(self, expr: str):
        """The value of a JavaScript expression in the page (JSON-able)."""
        raise NotImplementedError

    def click(self, selector: str) -> None:
        raise NotImplementedError

    def fill(self, selector: str, text: str) -> None:
        raise NotImplementedError

    def key(self, key: str, down: bool) -> None:
        raise NotImplementedError

    def _touch(self, phase: str, x: float, y: float) -> None:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def problems(self) -> list[str]:
        """What went wrong in the page since it was opened, as far as the driver tells: console
        errors, uncaught errors, failed requests and HTTP errors (Chromium and Firefox); WebKitWebDriver
        tells none of these (check the server's log for its requests)."""
        return []

    def wait(self, expr: str, timeout: float = 60, what: str = "") -> object:
        """Poll ``expr`` until it is truthy; its value, or AssertionError at the deadline. An error
        while a page is being replaced (a form sent, a reload) is polled over too."""
        deadline = time.monotonic() + timeout
        error = None
        while True:
            try:
                value = self.js(expr)
            except Exception as e:   # the engines' errors differ: Playwright's, Selenium's, the driver's
                value, error = None, e
            if value:
                return value
            if time.monotonic() > deadline:
                raise AssertionError(f"{self.name}: {what or expr} not within {timeout} s"
                                     + (f" (last error: {error})" if error else ""))
            time.sleep(0.05)

    def center(self, selector: str) -> tuple[float, float, float, float]:
        """(x, y) of the element's centre in the viewport, and its width and height."""
        r = self.js(f"(() => {{ const r = document.querySelector({json.dumps(selector)}).getBoundingClientRect();"
                    " return [r.x + r.width / 2, r.y + r.height / 2, r.width, r.height]; })()")
        return tuple(r)

    def drag(self, x0: float, y0: float, dx: float, dy: float, steps: int = 6) -> None:
        """Press at (x0, y0) and move by (dx, dy); held until release()."""
        self._touch("start", x0, y0)
        for i in range(1, steps + 1):
            self._touch("move", x0 + dx * i / steps, y0 + dy * i / steps)
        self._last = (x0 + dx, y0 + dy)

    def release(self) -> None:
        self._touch("end", *getattr(self, "_last", (0, 0)))


class Chromium(Engine):
    name = "chromium"

    def __init__(self, browser):
        self.browser = browser
        self.ctx = self.page = self.cdp = None

    def open(self, url):
        self.close()
        self.ctx = self.browser.new_context(viewport={"width": SIZE[0], "height": SIZE[1]}, has_touch=True)
        self.page = self.ctx.new_page()
        self.cdp = self.ctx.new_cdp_session(self.page)
        seen = self.seen = []
        self.page.on("console", lambda m: m.type == "error" and seen.append(f"console: {m.text}"))
        self.page.on("pageerror", lambda e: seen.append(f"error: {e}"))
        self.page.on("requestfailed", lambda r: seen.append(f"failed: {r.url} {r.failure}"))
        self.page.on("response", lambda r: r.status >= 400 and seen.append(f"{r.status}: {r.url}"))
        self.page.goto(url)

    def problems(self):
        return list(getattr(self, "seen", []))

    def js(self, expr):
        return self.page.evaluate(expr)

    def click(self, selector):
        self.page.click(selector)

    def fill(self, selector, text):
        self.page.fill(selector, text)

    def key(self, key, down):
        (self.page.keyboard.down if down else self.page.keyboard.up)(key)

    def _touch(self, phase, x, y):
        points = [] if phase == "end" else [{"x": x, "y": y}]
        self.cdp.send("Input.dispatchTouchEvent", {"type": f"touch{phase.capitalize()}", "touchPoints": points})

    def close(self):
        if self.ctx is not None:
            self.ctx.close()
            self.ctx = None


class Xvfb:
    """An X server of its own on a free display (-displayfd: the server picks it and says which)."""

    def __init__(self):
        if not shutil.which("Xvfb"):
            raise RuntimeError("Xvfb not found: apt-get install xvfb (tools/system-packages test)")
        r, w = os.pipe()
        self.proc = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", f"{SIZE[0]}x{SIZE[1] + 100}x24",
                                      "-nolisten", "tcp"], pass_fds=[w], stderr=subprocess.DEVNULL)
        os.close(w)
        self.fd = r   # open while the server runs: it writes the number, then a newline (a closed pipe kills it)
        said, deadline = b"", time.monotonic() + 30
        while not said.endswith(b"\n") and select.select([r], [], [], max(0, deadline - time.monotonic()))[0]:
            chunk = os.read(r, 64)
            if not chunk:
                break
            said += chunk
        if not said.strip().isdigit():
            self.stop()
            raise RuntimeError(f"Xvfb did not say its display within 30 s ({said!r})")
        self.display = f":{said.decode().strip()}"

    def stop(self):
        self.proc.terminate()
        self.proc.wait(10)
        os.close(self.fd)


class WebKit(Engine):
    name = "webkit"
    touch = False     # WebKitWebDriver delivers touch actions as mouse events (see the module's doc)

    def __init__(self):
        for path, package in ((WEBKIT_DRIVER, "webkit2gtk-driver"), (MINIBROWSER, "libwebkit2gtk-4.1-0")):
            if not Path(path).exists():
                raise RuntimeError(f"{path} not found: apt-get install {package} (tools/system-packages test)")
        from selenium import webdriver
        from selenium.webdriver.webkitgtk.options import Options
        from selenium.webdriver.webkitgtk.service import Service
        self.xvfb = Xvfb()
        options = Options()
        options.binary_location = MINIBROWSER
        options.add_argument("--automation")
        # LANG=C.UTF-8, as containers and CI have it: WebKitGTK then says navigator.language 'C', the
        # case that once stopped the teleop page (ide/build.mjs)
        env = {**os.environ, "DISPLAY": self.xvfb.display, "LANG": "C.UTF-8"}
        env.pop("LC_ALL", None)
        try:
            self.driver = webdriver.WebKitGTK(options=options, service=Service(executable_path=WEBKIT_DRIVER, env=env))
        except Exception:
            self.xvfb.stop()
            raise
        self.driver.set_window_size(*SIZE)
        self.driver.set_script_timeout(30)
        from selenium.webdriver.common.by import By
        from selenium.webdriver.common.keys import Keys
        self.by, self.keys = By, Keys

    def open(self, url):
        self.driver.get(url)

    def js(self, expr):   # (no init scripts here: the names of page_state.js come with each evaluation)
        return self.driver.execute_script(f"return {with_state(expr)};")

    def click(self, selector):
        self.driver.find_element(self.by.CSS_SELECTOR, selector).click()

    def fill(self, selector, text):
        el = self.driver.find_element(self.by.CSS_SELECTOR, selector)
        el.clear()
        el.send_keys(text)

    def key(self, key, down):
        from selenium.webdriver.common.action_chains import ActionChains
        k = {"ArrowUp": self.keys.ARROW_UP, "ArrowDown": self.keys.ARROW_DOWN, "ArrowLeft": self.keys.ARROW_LEFT,
             "ArrowRight": self.keys.ARROW_RIGHT, "Space": self.keys.SPACE}.get(key, key)
        chain = ActionChains(self.driver)
        (chain.key_down if down else chain.key_up)(k).perform()

    def _touch(self, phase, x, y):
        from selenium.webdriver.common.actions import interaction
        from selenium.webdriver.common.actions.action_builder import ActionBuilder
        from selenium.webdriver.common.actions.pointer_input import PointerInput
        actions = ActionBuilder(self.driver, mouse=PointerInput(interaction.POINTER_MOUSE, "mouse"), duration=0)
        if phase == "end":
            actions.pointer_action.pointer_up()
        else:
            actions.pointer_action.move_to_location(int(x), int(y))
            if phase == "start":
                actions.pointer_action.pointer_down()
        actions.perform()

    def close(self):
        pass

    def quit(self):
        try:
            self.driver.quit()
        finally:
            self.xvfb.stop()


class Firefox(Engine):
    name = "firefox"

    def __init__(self):
        if not Path(FIREFOX).exists():
            raise RuntimeError(f"{FIREFOX} not found: apt-get install firefox-esr (tools/system-packages test)")
        if not (ROOT / "tests" / "node" / "node_modules" / "puppeteer-core").exists():
            raise RuntimeError("puppeteer-core is not installed: cd tests/node && npm ci")
        self.log = tempfile.TemporaryFile(mode="w+", prefix="rosgate-firefox-")
        self.proc = subprocess.Popen(["node", str(FIREFOX_DRIVER)], cwd=FIREFOX_DRIVER.parent, text=True,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log,
                                     env={**os.environ, "FIREFOX": FIREFOX})
        first = self._read(START)
        if not first.get("ready"):
            self.quit()
            raise RuntimeError(f"Firefox did not start: {first}")
        self.version = first["version"]

    def _read(self, timeout: float) -> dict:
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        line = self.proc.stdout.readline() if ready else ""
        if not line:
            self.log.seek(0)
            raise RuntimeError(f"the Firefox driver said nothing within {timeout} s: {self.log.read()[-3000:]}")
        return json.loads(line)

    def _send(self, op: str, timeout: float = 60, **args):
        self.proc.stdin.write(json.dumps({"op": op, **args}) + "\n")
        self.proc.stdin.flush()
        answer = self._read(timeout)
        if not answer.get("ok"):
            raise RuntimeError(f"firefox {op} {args}: {answer.get('error')}")
        return answer["value"]

    def open(self, url):
        self._send("open", url=url, width=SIZE[0], height=SIZE[1])

    def js(self, expr):   # (as WebKit's)
        return self._send("js", expr=with_state(expr))

    def click(self, selector):
        self._send("click", selector=selector)

    def fill(self, selector, text):
        self._send("fill", selector=selector, text=text)

    def key(self, key, down):
        self._send("key", key=key, down=down)

    def problems(self):
        return self._send("problems")

    def _touch(self, phase, x, y):
        self._send("touch", phase=phase, x=x, y=y)

    def close(self):
        pass

    def quit(self):
        try:
            if self.proc.poll() is None:
                self.proc.stdin.write('{"op": "quit"}\n')
                self.proc.stdin.flush()
                self.proc.wait(30)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait()
