"""Artifacts as users install them: the sdist and wheel built with the ordinary tools (build, pip),
the wheel installed into a clean venv and started from another directory, and the ROS 2 package
built by colcon. Everything happens in a temporary directory; the checkout is only read."""

from __future__ import annotations

import os
import tarfile
from pathlib import Path

import pytest

from tests.support.install import TOOLS, copy_source, make_venv, run
from tests.support.process import ROOT


def pytest_collection_modifyitems(items):
    for item in items:
        if "tests/install/" in str(item.fspath).replace(os.sep, "/"):
            item.add_marker(pytest.mark.timeout(600))


@pytest.fixture(scope='session')
def work(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp('install')


@pytest.fixture(scope='session')
def tools(work) -> Path:
    """A venv with build and colcon (its python)."""
    if not (ROOT / 'ide' / 'vendor' / 'roslib.mjs').is_file():
        pytest.fail('the IDE is not built: make ide')
    python = make_venv(work / 'tools')
    run([python, '-m', 'pip', 'install', '-q', *TOOLS])
    return python


@pytest.fixture(scope='session')
def source(work) -> Path:
    """A copy of the checkout (others may be changing the checkout meanwhile)."""
    return copy_source(work / 'src')


@pytest.fixture(scope='session')
def sdist(tools, source, work) -> Path:
    """`python -m build --sdist` of the copy."""
    run([tools, '-m', 'build', '--sdist', '--outdir', work / 'dist', source])
    (path,) = (work / 'dist').glob('rosgate-*.tar.gz')
    return path


@pytest.fixture(scope='session')
def wheel(tools, sdist, work) -> Path:
    """The wheel pip builds from the sdist, as `pip install rosgate` does from an index."""
    run([tools, '-m', 'pip', 'wheel', '-q', '--no-deps', '-w', work / 'wheels', sdist])
    (path,) = (work / 'wheels').glob('rosgate-*.whl')
    return path


@pytest.fixture(scope='session')
def user_venv(wheel, work) -> Path:
    """A clean venv with only the wheel and its dependencies (its python)."""
    python = make_venv(work / 'user')
    run([python, '-m', 'pip', 'install', '-q', wheel])
    return python


@pytest.fixture(scope='session')
def sdist_tree(sdist, work) -> Path:
    """The sdist unpacked: what a workspace holds."""
    with tarfile.open(sdist) as tar:
        tar.extractall(work / 'unpacked', filter='data')
    (top,) = (work / 'unpacked').iterdir()
    return top
