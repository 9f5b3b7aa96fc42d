"""pip users: the sdist and the wheel carry the built IDE, the teleop page and the examples; the
wheel installed in a clean venv serves them from another directory, in Chromium, and bridges."""

from __future__ import annotations

import shutil
import tarfile
import zipfile
from contextlib import nullcontext
from pathlib import Path

import pytest

from tests.support import page_state
from tests.support.ide import CHROMIUM, CHROMIUM_ARGS
from tests.support.install import copy_source, run, started
from tests.support.ros import client

# Files of ide/ that only build the IDE or describe it; everything else must reach users.
IDE_BUILD_ONLY = {'package.json', 'package-lock.json', 'build.mjs', 'README.md', 'vendor/.built'}


def ide_files(source: Path) -> set[str]:
    """What the pages may load: ide/ less its build files, dotfiles and node_modules."""
    ide = source / 'ide'
    files = {p.relative_to(ide).as_posix() for p in ide.rglob('*')
             if p.is_file() and not any(part.startswith('.') or part in ('node_modules', '__pycache__')
                                        for part in p.relative_to(ide).parts)}
    return files - IDE_BUILD_ONLY


def example_files(source: Path) -> set[str]:
    return {p.name for p in (source / 'examples').iterdir() if p.is_file()}


def test_sdist_carries_the_built_ide_and_not_node_modules(sdist, source):
    with tarfile.open(sdist) as tar:
        names = {n.split('/', 1)[1] for n in tar.getnames() if '/' in n}
    assert {'ide/' + f for f in ide_files(source)} <= names
    assert {'examples/' + f for f in example_files(source)} <= names
    assert {'package.xml', 'launch/rosgate_launch.xml', 'resource/rosgate', 'setup.py', 'setup.cfg'} <= names
    assert not [n for n in names if 'node_modules' in n]


def test_wheel_carries_every_served_file(wheel, source):
    with zipfile.ZipFile(wheel) as whl:
        names = set(whl.namelist())
    prefix = 'gateway/_assets/'
    assert {n[len(prefix + 'ide/'):] for n in names if n.startswith(prefix + 'ide/')} == ide_files(source)
    assert {n[len(prefix + 'examples/'):] for n in names if n.startswith(prefix + 'examples/')} == example_files(source)
    assert 'gateway/_assets/ide/vendor/blockly/media/sprites.svg' in names
    assert not [n for n in names if 'node_modules' in n]


def test_the_installed_package_is_not_the_checkout(user_venv, tmp_path):
    out = run([user_venv, '-c', 'import gateway.settings as a; print(a.ide_dir()); print(a.examples_dir())'],
              cwd=tmp_path).stdout.split()
    site = user_venv.parent.parent / 'lib'
    for path in map(Path, out):
        assert path.is_relative_to(site) and path.parts[-3:-1] == ('gateway', '_assets'), path


@pytest.fixture(scope='module')
def installed(user_venv, tmp_path_factory):
    """`rosgate` of the clean venv, started in an empty directory elsewhere."""
    elsewhere = tmp_path_factory.mktemp('elsewhere')
    gw = started([user_venv.parent / 'rosgate', '--port', '0', '--address', '127.0.0.1', '--backend', 'sim',
                  '--programs-dir', elsewhere / 'programs'], cwd=elsewhere)
    yield gw
    gw.stop()


def test_startup_line_advertises_the_ide(installed):
    assert f'IDE http://127.0.0.1:{installed.port}/' in installed.line


def test_ide_and_teleop_work_in_chromium(installed, playwright):
    if not Path(CHROMIUM).exists():
        pytest.fail(f'Chromium not found at {CHROMIUM}: apt-get install chromium')
    with nullcontext(playwright) as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = page_state.install(browser.new_page())
            failed, errors = [], []
            page.on('response', lambda r: r.status >= 400 and failed.append(f'{r.status} {r.url}'))
            page.on('pageerror', lambda e: errors.append(str(e)))
            page.goto(installed.http_url)
            page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=30000)
            page.wait_for_function("document.body?.dataset.connection === 'connected'", timeout=15000)
            blocks = page.evaluate('rosgateIde.workspace.getToolbox().getToolboxItems().length')
            assert blocks > 3   # Blockly injected with the toolbox's categories
            assert page.evaluate("typeof Blockly.Blocks['controls_repeat_ext']") == 'object'
            examples = page.evaluate("fetch('examples/index.json').then(r => r.json())")
            assert examples, 'the examples index is served'
            page.goto(installed.http_url + 'teleop')
            page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=30000)
            page.wait_for_function("document.body?.dataset.connection === 'connected'", timeout=15000)
            assert not failed, failed
            assert not errors, errors
        finally:
            browser.close()


def test_roslibpy_round_trip(installed):
    import roslibpy
    with client(installed) as ros:
        srv = roslibpy.Service(ros, '/add_two_ints', 'example_interfaces/srv/AddTwoInts')
        assert srv.call(roslibpy.ServiceRequest({'a': 20, 'b': 22}), timeout=10)['sum'] == 42


def test_startup_line_says_when_the_ide_is_missing(user_venv, installed, tmp_path):
    """A package whose IDE is incomplete says so instead of advertising pages that answer 404."""
    vendor = Path(run([user_venv, '-c', 'import gateway.settings as a; print(a.ide_dir() / "vendor")'],
                      cwd=tmp_path).stdout.strip())
    aside = tmp_path / 'vendor'
    shutil.move(vendor, aside)
    try:
        gw = started([user_venv.parent / 'rosgate', '--port', '0', '--address', '127.0.0.1', '--backend', 'sim',
                      '--programs-dir', tmp_path / 'programs'], cwd=tmp_path)
        gw.stop()
    finally:
        shutil.move(aside, vendor)
    assert 'IDE unavailable' in gw.line and 'vendor/roslib.mjs' in gw.line and 'IDE http' not in gw.line


def test_building_without_the_built_ide_fails_clearly(tools, tmp_path):
    src = copy_source(tmp_path / 'src', with_built_ide=False)
    done = run([tools, 'setup.py', '-q', 'build', '--build-base', tmp_path / 'build'], cwd=src, check=False)
    assert done.returncode != 0
    assert 'the IDE is not built' in done.stderr + done.stdout and 'make ide' in done.stderr + done.stdout
