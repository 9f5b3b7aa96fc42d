"""The fixtures every test folder shares (registered by tests/conftest.py through ``pytest_plugins``):
gateways started for the session or for a module (launch), the shared sim gateway and a roslibpy
client of it, the tokens file of tests.support.auth, Playwright and one Chromium per test process."""

from __future__ import annotations

import asyncio
from contextlib import ExitStack
from pathlib import Path

import pytest

from tests.support import page_state
from tests.support.auth import tokens_toml
from tests.support.process import ROOT, GatewayProcess
from tests.support.ros import client


_SETTING_UP: list[str] = []   # the scopes of the fixtures being set up, the innermost last
_LIVES = {'session': 'session', 'package': 'session', 'module': 'module', 'class': 'module'}


@pytest.hookimpl(hookwrapper=True)
def pytest_fixture_setup(fixturedef, request):
    _SETTING_UP.append(fixturedef.scope)
    try:
        yield
    finally:
        _SETTING_UP.pop()


class Lifetimes:
    """What ``start_gateway`` started, by how long it lives: as long as what started it (a
    session fixture: the session; a module or class fixture: its module; a function fixture or a
    test's own body: that test). Measured before: a module's gateway lived to the session's end,
    so a test process held some 30 idle gateways (each about 1 % of a core and 100 MB) by the end."""

    def __init__(self):
        self.stops: dict[str, list] = {'session': [], 'module': [], 'function': []}

    def add(self, stop) -> None:
        self.stops[_LIVES.get(_SETTING_UP[-1], 'function') if _SETTING_UP else 'function'].append(stop)

    def end(self, lifetime: str) -> None:
        stops, self.stops[lifetime] = self.stops[lifetime], []
        for stop in reversed(stops):
            stop()


_lifetimes = Lifetimes()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item, nextitem):
    yield   # the test's fixtures (and, at a module's last test, the module's) are torn down
    _lifetimes.end('function')
    if nextitem is None or nextitem.path != item.path:
        _lifetimes.end('module')


@pytest.fixture(scope='session')
def start_gateway():
    """Factory: start_gateway(*flags) -> a GatewayProcess, stopped when what started it ends (a
    session fixture: the session; a module fixture: its module; a function fixture or a test: the
    test, once its fixtures are torn down)."""
    with ExitStack() as started:
        def start(*args: str, env: dict | None = None) -> GatewayProcess:
            gw = GatewayProcess(*args, env=env)
            started.callback(gw.stop)
            _lifetimes.add(gw.stop)
            return gw

        yield start
        _lifetimes.end('function')
        _lifetimes.end('module')
        _lifetimes.end('session')


@pytest.fixture(scope='session')
def tokens_file(tmp_path_factory):
    """A tokens file giving each of tests.support.auth's TOKENS its person and role."""
    path = tmp_path_factory.mktemp('auth') / 'tokens.toml'
    path.write_text(tokens_toml())
    return str(path)


@pytest.fixture(scope='module')
def launch(start_gateway):
    """start_gateway(*flags) for this module: every gateway it started is stopped at module end."""
    with ExitStack() as started:
        def start(*flags: str, env: dict | None = None):
            gw = start_gateway(*flags, env=env)
            started.callback(gw.stop)
            return gw

        yield start


@pytest.fixture(scope='session')
def gateway(start_gateway):
    """The shared sim gateway (demo nodes, fast Fibonacci)."""
    return start_gateway('--fibonacci-interval', '0.05', '--unregister-timeout', '0.5')


def client_of(gateway: str, scope: str = 'function', kind=client, doc: str = ''):
    """A fixture: a roslibpy connection (``kind``: ``ros.client``, or ``ros.RosClient`` with its
    watches) to the gateway the fixture named ``gateway`` gives, kept for ``scope``."""
    @pytest.fixture(scope=scope)
    def connected(request):
        with kind(request.getfixturevalue(gateway)) as ros:
            yield ros
    connected.__doc__ = doc or f'A roslibpy client of {gateway}.'
    return connected


ros = client_of('gateway')


class Browsers:
    """Playwright's driver and one Chromium for the whole test process, each started at first need
    (measured: a driver and a Chromium started per module cost about 1.2 CPU-seconds and 2-3 s of a
    loaded machine's wall time each, some 75 times a run).

    The sync API runs its event loop in the test thread, in a greenlet of its own, and marks it as
    the thread's running loop after every call: while it is marked, ``asyncio.run()`` and the
    asyncio tests of a later module fail ("cannot be called from a running event loop"). So the
    mark is taken off between modules (``park``) and put back when a module asks for Playwright
    (``driver``): nothing runs that loop in between, the driver's messages wait in its pipe."""

    def __init__(self):
        self._manager = self._driver = self._loop = self._chromium = None

    def driver(self):
        if self._driver is None:
            from playwright.sync_api import sync_playwright
            self._manager = sync_playwright()
            self._driver = self._manager.start()
            self._loop = asyncio.events._get_running_loop()
        else:
            asyncio.events._set_running_loop(self._loop)
        return self._driver

    def park(self) -> None:
        if self._driver is not None and asyncio.events._get_running_loop() is self._loop:
            asyncio.events._set_running_loop(None)

    def chromium(self):
        from tests.support.ide import ARTIFACTS, CHROMIUM, CHROMIUM_ARGS
        if self._chromium is None or not self._chromium.is_connected():
            if not Path(CHROMIUM).exists():
                pytest.fail(f"Chromium not found at {CHROMIUM}: apt-get install chromium")
            if not (ROOT / "ide" / "vendor" / "roslib.mjs").exists():
                pytest.fail("the IDE's vendor/ is not built: cd ide && npm ci && npm run build")
            ARTIFACTS.mkdir(exist_ok=True)
            self._chromium = patient(self.driver().chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS))
        return self._chromium

    def stop(self) -> None:
        if self._driver is None:
            return
        self.driver()
        try:
            if self._chromium is not None and self._chromium.is_connected():
                self._chromium.close()
        finally:
            self._manager.__exit__(None, None, None)
            self._driver = self._chromium = None


PATIENCE_MS = 90_000   # a page's waits, clicks and loads without a timeout of their own (Playwright's: 30 s)


def patient(browser):
    """The browser, whose new contexts and pages wait ``PATIENCE_MS`` where a call names no
    timeout: a deadline is patience, not a bar (a page's load took over 30 s at load 50); and
    see the pages' state by the names of tests/support/page_state.js."""
    new_context, new_page = browser.new_context, browser.new_page

    def patient_context(*args, **kwargs):
        ctx = page_state.install(new_context(*args, **kwargs))
        ctx.set_default_timeout(PATIENCE_MS)
        return ctx

    def patient_page(*args, **kwargs):
        page = new_page(*args, **kwargs)
        page_state.install(page.context)
        page.context.set_default_timeout(PATIENCE_MS)
        return page

    browser.new_context, browser.new_page = patient_context, patient_page
    return browser


@pytest.fixture(scope="session")
def browsers():
    """The test process's Playwright driver and Chromium (``Browsers``), stopped at its end."""
    started = Browsers()
    yield started
    started.stop()


@pytest.fixture(scope="module")
def playwright(browsers):
    """Playwright's driver for this module (one per test process, ``Browsers``): tests that start
    a Chromium of their own (other flags, another network namespace) start it here and close it."""
    yield browsers.driver()
    browsers.park()


@pytest.fixture(scope="module")
def chromium(playwright, browsers):
    """The test process's Chromium; a module's tests are kept apart by browser contexts of their
    own, and a context a module left open is closed at its end."""
    browser = browsers.chromium()
    yield browser
    if browser.is_connected():
        for ctx in list(browser.contexts):
            ctx.close()
