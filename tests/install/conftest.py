"""Artifacts as users install them: the sdist and wheel built with the ordinary tools (build, pip),
the wheel installed into a clean venv and started from another directory, and the ROS 2 package
built by colcon. Everything happens in a temporary directory; the checkout is only read."""

from __future__ import annotations

import os
import shutil
import subprocess
import tarfile
import venv
from pathlib import Path

import pytest

from tests.conftest import ROOT, Started

# Tools a developer or a ROS 2 user has; they live in their own venv, not in the project's.
TOOLS = ['build>=1', 'colcon-core>=0.15', 'colcon-ros>=0.4', 'setuptools>=77']   # colcon builds with this setuptools
# What a source copy leaves out: generated, local or heavy (ide/vendor is built and kept).
NOT_SOURCE = shutil.ignore_patterns('.git', '.venv*', 'node_modules', 'build', 'dist', '*.egg-info', '__pycache__',
                                    '.pytest_cache', '.hypothesis', '.bench', 'artifacts', '.built')


def pytest_collection_modifyitems(items):
    for item in items:
        if "tests/install/" in str(item.fspath).replace(os.sep, "/"):
            item.add_marker(pytest.mark.timeout(600))


def run(cmd: list, *, cwd=None, env=None, timeout: float = 600, check: bool = True) -> subprocess.CompletedProcess:
    """Runs a command; on failure the assertion shows its output."""
    clean = {k: v for k, v in os.environ.items() if k not in ('PYTHONPATH', 'VIRTUAL_ENV', 'PYTHONHOME')}
    done = subprocess.run([str(c) for c in cmd], cwd=cwd, env={**clean, **(env or {})}, capture_output=True,
                          text=True, timeout=timeout)
    if check:
        assert done.returncode == 0, f'{cmd} exited {done.returncode}\n{done.stdout[-4000:]}\n{done.stderr[-4000:]}'
    return done


def make_venv(path: Path) -> Path:
    venv.create(path, with_pip=True, clear=True)
    return path / 'bin' / 'python'


def copy_source(dest: Path, *, with_built_ide: bool = True) -> Path:
    """The checkout as a clone holds it after `make ide` (or without the built IDE)."""
    shutil.copytree(ROOT, dest, ignore=NOT_SOURCE, symlinks=True)
    if not with_built_ide:
        shutil.rmtree(dest / 'ide' / 'vendor', ignore_errors=True)
    return dest


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


def started(cmd: list, cwd: Path, env: dict | None = None) -> Started:
    """An installed rosgate command started in cwd, without this checkout's Python environment."""
    clean = {k: v for k, v in os.environ.items() if k not in ('PYTHONPATH', 'VIRTUAL_ENV', 'PYTHONHOME')}
    return Started(cmd, cwd, {**clean, **(env or {})}, timeout=60)
