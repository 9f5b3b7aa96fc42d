"""Browser fixtures (Chromium itself is tests/support/fixtures.py's, one per module): pages
of the IDE, gateways with the simulated turtlesim and rover, and independent roslibpy clients that
watch what the robots do."""

from __future__ import annotations

import os
import types
from contextlib import ExitStack

import pytest

from tests.support.fixtures import client_of
from tests.support.ide import TABLET, IdePage
from tests.support.lesson import TOKENS
from tests.support.process import ROOT, GatewayProcess
from tests.support.ros import RosClient


def pytest_collection_modifyitems(items):
    for item in items:
        if "tests/ide/" in str(item.fspath).replace(os.sep, "/"):
            item.add_marker(pytest.mark.timeout(180))


@pytest.fixture
def ide_factory(chromium):
    with ExitStack() as contexts:
        def make(gateway, url: str | None = None, **context_args) -> IdePage:
            ctx = chromium.new_context(**{"viewport": {"width": 1400, "height": 860}, **context_args})
            contexts.callback(ctx.close)
            return IdePage(ctx.new_page(), gateway).open(url)

        yield make


@pytest.fixture(scope="module")
def turtle_gateway(start_gateway):
    return start_gateway("--robot", "turtlesim", "--fibonacci-interval", "0.05")


@pytest.fixture(scope="module")
def rover_gateway(start_gateway):
    return start_gateway("--robot", "rover", "--fibonacci-interval", "0.05")


turtle = client_of("turtle_gateway", "module", RosClient, "A client of the module's turtlesim gateway, kept for the module.")
turtle_ros = client_of("turtle_gateway", kind=RosClient)
rover_ros = client_of("rover_gateway", kind=RosClient)


@pytest.fixture
def rover():
    """A fresh rover gateway of its own (the test may change the rover's state) and a client for it."""
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


@pytest.fixture
def tablets(chromium):
    """tablet(gw, who, viewport): a browser context of a student, signed in through /login."""
    with ExitStack() as contexts:
        def make(gw, who: str | None, viewport=TABLET):
            ctx = chromium.new_context(viewport=viewport, has_touch=True)
            contexts.callback(ctx.close)
            if who is not None:
                r = ctx.request.post(gw.http_url + "login", form={"token": TOKENS[who], "next": "/whoami"})
                assert r.ok, r.status
            return ctx

        yield make
