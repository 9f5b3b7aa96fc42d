"""The fixtures every test folder shares (registered by tests/conftest.py through ``pytest_plugins``):
gateways started for the session or for a module (launch), the shared sim gateway and a roslibpy
client of it, the tokens file of tests.support.auth, Playwright and one Chromium per module."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import pytest

from tests.support.auth import tokens_toml
from tests.support.process import ROOT, GatewayProcess
from tests.support.ros import client


@pytest.fixture(scope='session')
def start_gateway():
    """Factory: start_gateway(*flags) -> a GatewayProcess, stopped at the end of the session."""
    with ExitStack() as started:
        def start(*args: str, env: dict | None = None) -> GatewayProcess:
            gw = GatewayProcess(*args, env=env)
            started.callback(gw.stop)
            return gw

        yield start


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


@pytest.fixture(scope="module")
def playwright():
    """Playwright's driver, once per module (a second sync_playwright() in one thread fails): tests
    that start a Chromium of their own (other flags, another network namespace) start it here. Not
    once per session: its event loop runs in the test thread while it lives, and a later module's
    asyncio.run() or asyncio test then fails ("cannot be called from a running event loop")."""
    from playwright.sync_api import sync_playwright
    with sync_playwright() as p:
        yield p


@pytest.fixture(scope="module")
def chromium(playwright):
    """One Chromium per module; its tests are kept apart by browser contexts of their own."""
    from tests.support.ide import ARTIFACTS, CHROMIUM, CHROMIUM_ARGS
    if not Path(CHROMIUM).exists():
        pytest.fail(f"Chromium not found at {CHROMIUM}: apt-get install chromium")
    if not (ROOT / "ide" / "vendor" / "roslib.mjs").exists():
        pytest.fail("the IDE's vendor/ is not built: cd ide && npm ci && npm run build")
    ARTIFACTS.mkdir(exist_ok=True)
    browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
    yield browser
    browser.close()
