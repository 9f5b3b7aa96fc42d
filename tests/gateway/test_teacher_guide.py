"""docs/teacher.md followed literally: its tokens.toml and its class start command, run as written
(in the rosgate folder, where `make run` put `.venv/`), start a gateway whose pages answer, print
the pages' addresses framed after the start-up log, and take the guide's tokens."""

from __future__ import annotations

import os
import re
import shlex
import urllib.request

import roslibpy

from tests.support.process import ROOT, START, Started
from tests.support.wait import wait_for

GUIDE = ROOT / 'docs' / 'teacher.md'


def fenced(text: str, lang: str, marker: str) -> str:
    """The first fenced block of language lang that contains marker."""
    for block in re.findall(rf'```{lang}\n(.*?)```', text, flags=re.S):
        if marker in block:
            return '\n'.join(line.strip() for line in block.splitlines())
    raise AssertionError(f'no ```{lang} block with {marker!r} in {GUIDE}')


def test_the_guides_class_command_runs_as_written(tmp_path):
    text = GUIDE.read_text()
    tokens = fenced(text, 'toml', '[[tokens]]')
    command = fenced(text, 'sh', '--fleet 30 --exclusive-control')   # the lesson's class gateway
    command = command.replace('\\\n', ' ')
    argv = shlex.split(command)
    assert argv[0] == '.venv/bin/rosgate', argv[0]          # what `make run` installs, by its path
    bare = [line for block in re.findall(r'```sh\n(.*?)```', text, flags=re.S)
            for line in block.splitlines() if line.strip().startswith('rosgate ')]
    assert not bare, bare                                    # nor does any other command of the guide say less
    # the rosgate folder as `make run` leaves it (its .venv), with the guide's tokens.toml in it
    (tmp_path / '.venv').symlink_to(ROOT / '.venv')
    (tmp_path / 'tokens.toml').write_text(tokens)
    home = tmp_path / 'home'
    home.mkdir()
    env = {**os.environ, 'HOME': str(home), 'XDG_DATA_HOME': str(home / 'data'), 'PYTHONPATH': str(ROOT)}
    # the guide's port is 9090; here a free one (other tests run at the same time), and loopback
    gw = Started([*argv, '--port', '0', '--address', '127.0.0.1'], cwd=tmp_path, env=env, timeout=START)
    try:
        rules, framed = 0, []
        while rules < 2:                      # the frame follows the one-line form at once
            line = gw.proc.stdout.readline()
            assert line, framed
            rules += bool(re.fullmatch(r'=+\n', line))
            framed.append(line)
        base = f'http://127.0.0.1:{gw.port}/'
        assert framed[0] == '\n' and re.fullmatch(r'=+\n', framed[1]), framed
        for page in ('', 'teleop', 'class'):
            assert any(line.endswith(f' {base}{page}\n') for line in framed), framed
        # the pages answer (the class view sends a browser without a token to sign in)
        for page in ('', 'teleop'):
            with urllib.request.urlopen(base + page, timeout=10) as r:
                assert r.status == 200 and b'<html' in r.read()
        # the guide's tokens: the teacher is an admin, and the class has its 30 stations
        token = re.search(r'name = "teacher"\s*role = "admin"\s*token = "([^"]+)"', tokens).group(1)
        ros = roslibpy.Ros(f'ws://127.0.0.1:{gw.port}/?token={token}')
        ros.run(timeout=10)
        try:
            box = []
            roslibpy.Topic(ros, '/rosgate/stations', 'std_msgs/msg/String').subscribe(box.append)
            wait_for(lambda: box, 10)
            assert '"/s30"' in box[-1]['data']
            done = roslibpy.Service(ros, '/fleet/release_all', 'std_srvs/srv/Empty').call(
                roslibpy.ServiceRequest({}), timeout=10)
            assert done == {}
        finally:
            ros.close()
    finally:
        assert gw.stop() == 0, gw.log_text()[-3000:]
