"""Commands of the installation tests, run outside this checkout's Python environment: a command
whose failure shows its output, a venv, a source copy as a clone holds it, an installed rosgate started."""

from __future__ import annotations

import os
import shutil
import subprocess
import venv
from pathlib import Path

from tests.support.process import ROOT, START, Started

# Tools a developer or a ROS 2 user has; they live in their own venv, not in the project's.
TOOLS = ['build>=1', 'colcon-core>=0.15', 'colcon-ros>=0.4', 'setuptools>=77']   # colcon builds with this setuptools
# What a source copy leaves out: generated, local or heavy (ide/vendor is built and kept).
NOT_SOURCE = shutil.ignore_patterns('.git', '.venv*', 'node_modules', 'build', 'dist', '*.egg-info', '__pycache__',
                                    '.pytest_cache', '.hypothesis', '.bench', 'artifacts', '.built')


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


def started(cmd: list, cwd: Path, env: dict | None = None) -> Started:
    """An installed rosgate command started in cwd, without this checkout's Python environment."""
    clean = {k: v for k, v in os.environ.items() if k not in ('PYTHONPATH', 'VIRTUAL_ENV', 'PYTHONHOME')}
    return Started(cmd, cwd, {**clean, **(env or {})}, timeout=START)
