"""Private parts of libraries the gateway and the programs' runtime lean on: each release range
pinned to what was tested, and each private part checked at start, so a release that renames one
stops the gateway or the program with a sentence instead of silently changing what they do."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from importlib.metadata import version

import pytest
from packaging.requirements import Requirement

from gateway.web import fastio, socket
from tests.support.process import ROOT, GatewayProcess
from tests.support.runs import RUNTIME

HANG = 60   # s; a failure here is an answer within seconds, the old code's silence a hang
RUNTIME_TESTED = next((line.split('"')[1] for line in RUNTIME.splitlines() if line.startswith('ROSLIBPY_TESTED')), None)


def pinned() -> dict[str, Requirement]:
    project = tomllib.loads((ROOT / 'pyproject.toml').read_text())['project']
    return {r.name: r for r in map(Requirement, project['dependencies'])}


@pytest.mark.parametrize('name', ['tornado', 'roslibpy', 'rosbags', 'picows', 'uvloop'])
def test_pins_have_an_upper_bound_and_hold_the_installed_release(name):
    req = pinned()[name]
    assert any(spec.operator == '<' for spec in req.specifier), f'{req} has no upper bound'
    assert req.specifier.contains(version(name)), f'{name} {version(name)} is outside {req}'


def test_the_sentences_name_the_pinned_ranges():
    assert pinned()['tornado'] == Requirement(socket.TORNADO_TESTED)
    assert pinned()['roslibpy'] == Requirement(RUNTIME_TESTED)


def test_picows_is_pinned_to_the_range_whose_protocol_the_gateway_builds():
    """fastio builds picows's server protocol itself (its constructor is not public API): a release
    outside the tested range leaves every connection to tornado instead of failing."""
    assert pinned()['picows'].specifier == Requirement(fastio.PICOWS_TESTED).specifier
    assert fastio.available() == Requirement(fastio.PICOWS_TESTED).specifier.contains(version('picows'))
    assert [fastio._tested(v) for v in ('2.3.1', '2.3.9', '2.3.0', '2.4.0', '3.0', 'x')] == [
        True, True, False, False, False, False]


def test_installed_tornado_has_the_private_parts():
    socket.check_tornado()     # raises, naming what is missing, on a tornado without them


def env() -> dict:
    return {**os.environ, 'PYTHONPATH': str(ROOT)}


def test_a_tornado_without_them_stops_the_gateway_at_start(tmp_path):
    """As a tornado release that renamed _handle_message would: the gateway does not start."""
    renamed = ('import runpy, sys, tornado.websocket as w\n'
               'P = w.WebSocketProtocol13\n'
               'P._on_frame_message = P._handle_message\n'
               'del P._handle_message\n'
               "sys.argv = ['rosgate', '--port', '0', '--address', '127.0.0.1', '--robot', 'none',"
               f" '--programs-dir', {str(tmp_path)!r}]\n"
               "runpy.run_module('gateway', run_name='__main__', alter_sys=True)\n")
    try:
        done = subprocess.run([sys.executable, '-c', renamed], capture_output=True, text=True, timeout=HANG,
                              cwd=ROOT, env={**env(), 'XDG_DATA_HOME': str(tmp_path)})
    except subprocess.TimeoutExpired as e:
        pytest.fail(f'the gateway ran on a tornado without _handle_message: {e.stdout!r}')
    assert done.returncode != 0 and 'websocket' not in done.stdout
    assert 'WebSocketProtocol13._handle_message' in done.stderr, done.stderr[-2000:]
    assert socket.TORNADO_TESTED in done.stderr


REFUSED = 'rt.publish("/forbidden/x", "std_msgs/msg/String", {"data": "hi"})'


def program(prefix: str = '') -> str:
    """A generated program that publishes where the gateway refuses it, forever unless that ends it."""
    body = f'    while True:\n        {REFUSED}\n        rt.sleep(0.05)\n'
    return f'{prefix}{RUNTIME}\n\ndef main():\n{body}\n\nif __name__ == "__main__":\n    run(main)\n'


@pytest.fixture(scope='module')
def refusing():
    gw = GatewayProcess('--robot', 'none', '--topics-pub-glob', "['/allowed/*']")
    yield gw
    gw.stop()


def run_program(gw, source: str, tmp_path) -> subprocess.CompletedProcess:
    path = tmp_path / 'prog.py'
    path.write_text(source)
    try:
        return subprocess.run([sys.executable, str(path), '--url', gw.ws_url], capture_output=True, text=True,
                              timeout=HANG, env=env())
    except subprocess.TimeoutExpired:
        pytest.fail(f'the program did not end within {HANG} s although its publishes were refused')


def test_a_refused_publish_ends_the_program(refusing, tmp_path):
    done = run_program(refusing, program(), tmp_path)
    assert done.returncode == 1
    assert '/forbidden/x' in done.stdout + done.stderr and 'not allowed' in done.stdout + done.stderr


RENAMED_TABLE = '''import roslibpy.comm.comm as _comm
_init = _comm.RosBridgeProtocol.__init__
def _renamed(self, *args, **kwargs):   # as a roslibpy release that renamed the table would
    _init(self, *args, **kwargs)
    self._handlers = self.__dict__.pop("_message_handlers")
_comm.RosBridgeProtocol.__init__ = _renamed
'''


def test_a_roslibpy_without_the_table_stops_the_program_at_start(refusing, tmp_path):
    done = run_program(refusing, program(RENAMED_TABLE), tmp_path)
    assert done.returncode != 0
    assert "RosBridgeProtocol._message_handlers" in done.stderr, done.stderr[-2000:]
    assert RUNTIME_TESTED in done.stderr
