"""How the suite is spread over parallel test processes (pytest-xdist, ``-n 2``: ``UnitScheduling``).

A file is the unit a process takes whole: its module fixtures (a gateway, a browser context's
state) are made once, and its tests keep their order. tests/install/ is one unit: its session
fixtures build the sdist, the wheel and two venvs, which every process taking one of its files
would build again. Nothing else needs to be kept apart: every gateway listens on a port of its own
(port 0), nginx and PostgreSQL on free ports in folders of their own, and the home-link namespaces
are named after the process that makes them.

Units are handed out in collection order, so the longest ones go first: a long file started last
leaves the other process idle at the end (measured: SLOW lists the files that took longest,
``--durations`` summed per file, slowest first)."""

from __future__ import annotations

import pytest

try:
    from xdist.scheduler import LoadScopeScheduling
except ImportError:   # no pytest-xdist: the suite runs in one process
    LoadScopeScheduling = None

SLOW = (
    'tests/install/',
    'tests/ide/test_home_link.py',
    'tests/ide/test_first_lesson.py',
    'tests/ide/test_class_lesson.py',
    'tests/ide/test_lti.py',
    'tests/ide/test_lesson.py',
    'tests/fuzz/',
    'tests/ide/test_robot_runs.py',
    'tests/ide/test_nginx_proxy.py',
    'tests/runs/test_run_sandbox.py',
    'tests/security/test_bookings.py',
    'tests/ide/test_booking.py',
)
TOGETHER = ('tests/install/',)   # folders that are one unit


def unit(nodeid: str) -> str:
    path = nodeid.split('::', 1)[0]
    return next((folder for folder in TOGETHER if path.startswith(folder)), path)


def rank(nodeid: str) -> int:
    return next((i for i, prefix in enumerate(SLOW) if nodeid.startswith(prefix)), len(SLOW))


def pytest_collection_modifyitems(config, items):
    items.sort(key=lambda item: rank(item.nodeid))   # stable: a file keeps its order


if LoadScopeScheduling is not None:
    class UnitScheduling(LoadScopeScheduling):
        """xdist's file-by-file scheduling with ``unit`` as the scope: tests/install/ goes to one process
        (pytest-xdist's own ``loadfile`` would split it, ``loadgroup`` did)."""

        def _split_scope(self, nodeid: str) -> str:
            return unit(nodeid)

    def pytest_xdist_make_scheduler(config, log):
        return UnitScheduling(config, log)
