"""How the tests see a page's state (tests/support/page_state.js): the names ``rosgateIde``,
``teleop``, ``classView``, ``twin``, ``inspect``, ``rosgateRecorder`` and ``rosgateBooking`` on
``window``, read from the page's entry module's exports. The pages set no globals."""

from __future__ import annotations

from pathlib import Path

SCRIPT = (Path(__file__).with_name("page_state.js")).read_text().rstrip().rstrip(";")


def install(target):
    """Adds the script to a Playwright context or page: it runs in every document opened after."""
    target.add_init_script(script=SCRIPT)
    return target


def with_state(expr: str) -> str:
    """An expression that installs the names first (for drivers without init scripts: WebKitGTK's
    WebDriver, Firefox's BiDi), then is ``expr``."""
    return f"({SCRIPT}, ({expr}))"
