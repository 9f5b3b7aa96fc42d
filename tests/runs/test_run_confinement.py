"""What a robot-side run may reach besides the gateway's websocket (nothing), who it is outside
its box (never root), and who may read it (its starter and admins), against a gateway started as a
class would (``--auth --exclusive-control --allow-runs``). The same on the real ROS graph:
tests/backends/test_run_graph.py."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from gateway.runs import sandbox
from gateway.runs.sandbox import Sandbox, SandboxUnavailable, reachable, unreadable
from tests.support.auth import TOKENS, tokens_toml
from tests.support.http import api
from tests.support.process import descendants, uids
from tests.support.runs import ended, program, state_of
from tests.support.wait import wait_for
from tests.support.wsclient import Client


@pytest.fixture(scope='module')
def class_gw(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('confined')
    (folder / 'tokens.toml').write_text(tokens_toml())
    return start_gateway('--robot', 'turtlesim', '--fleet', '4', '--allow-runs', '--exclusive-control',
                         '--runs-dir', str(folder / 'runs'), '--auth', str(folder / 'tokens.toml'))


def started(gw, source: str, ns: str, who: str = 'operator') -> str:
    status, body = api(gw, 'POST', '/api/runs', {'source': source, 'ns': ns, 'name': 'confined'}, token=TOKENS[who])
    assert status == 201, body
    return body['id']


def test_a_runs_state_and_output_are_its_starters_and_the_admins(class_gw):
    run_id = started(class_gw, 'print("alice\'s secret")', '/s01')
    assert "alice's secret" in ended(class_gw, run_id, token=TOKENS['operator'])['output']
    assert "alice's secret" in state_of(class_gw, run_id, TOKENS['admin'])['output']
    for who in ('operator2', 'viewer'):
        status, body = api(class_gw, 'GET', f'/api/runs/{run_id}', token=TOKENS[who])
        assert status == 403 and 'alice' in body['error'], (who, body)
        assert 'secret' not in str(body)
        status, body = api(class_gw, 'GET', '/api/runs', token=TOKENS[who])
        assert status == 200 and run_id not in [r['id'] for r in body['runs']], (who, body)
    for who in ('operator', 'admin'):
        assert run_id in [r['id'] for r in api(class_gw, 'GET', '/api/runs', token=TOKENS[who])[1]['runs']]
    status, body = api(class_gw, 'DELETE', f'/api/runs/{run_id}', token=TOKENS['operator2'])
    assert status == 403, body


def test_a_runs_output_topic_is_its_starters_and_the_admins(class_gw):
    run_id = started(class_gw, 'print("alice\'s output")', '/s01')
    ended(class_gw, run_id, token=TOKENS['operator'])
    topic = f'/rosgate/runs/{run_id}/output'
    for who in ('operator2', 'viewer'):
        with Client(class_gw.ws_url, TOKENS[who]) as bob:
            refused = bob.refusal({'op': 'subscribe', 'topic': topic, 'type': 'std_msgs/msg/String', 'id': 'peek'})
            assert refused is not None and 'alice' in refused['msg'] and 'peek' in str(refused), (who, refused)
    for who in ('operator', 'admin'):
        with Client(class_gw.ws_url, TOKENS[who]) as ok:
            assert ok.refusal({'op': 'subscribe', 'topic': f'/rosgate/runs/{run_id}/state',
                               'type': 'std_msgs/msg/String', 'id': 'mine'}) is None, who


def test_no_process_of_a_run_is_root_seen_from_the_gateway(class_gw):
    run_id = started(class_gw, 'import os, time\nprint("up", os.getuid(), flush=True)\ntime.sleep(60)', '/s02')
    try:
        body = wait_for(lambda: (lambda b: b if 'up' in b['output'] else None)(state_of(class_gw, run_id,
                                                                                     TOKENS['operator'])), 60)
        assert 'up 1000' in body['output']                     # its uid inside the box
        procs = {p: uids(p) for p in descendants(class_gw.pid)}
        print(procs)
        assert len(procs) >= 3, procs     # bwrap, its init, the program, the relay
        assert all(u and 0 not in u for u in procs.values()), procs
    finally:
        api(class_gw, 'DELETE', f'/api/runs/{run_id}', token=TOKENS['admin'])
    assert ended(class_gw, run_id, token=TOKENS['admin'])['state'] == 'stopped'


PROBE = '''import socket
for kind, name, port in ((socket.SOCK_STREAM, "tcp", {tcp}), (socket.SOCK_DGRAM, "udp", {udp})):
    s = socket.socket(socket.AF_INET, kind)
    s.settimeout(3)
    try:
        if name == "tcp":
            s.connect(("127.0.0.1", port))
            s.sendall(b"from the run")
        else:
            for _ in range(20):
                s.sendto(b"from the run", ("127.0.0.1", port))
        print(name, "sent", flush=True)
    except OSError as e:
        print(name, "refused:", e, flush=True)
'''


def test_a_checkers_listeners_on_loopback_hear_nothing_from_a_run(class_gw):
    tcp = socket.create_server(('127.0.0.1', 0))
    tcp.settimeout(0.3)
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(('127.0.0.1', 0))
    udp.settimeout(0.3)
    try:
        run_id = started(class_gw, PROBE.format(tcp=tcp.getsockname()[1], udp=udp.getsockname()[1]), '/s03')
        final = ended(class_gw, run_id, token=TOKENS['operator'])
        assert final['state'] == 'finished' and final['output'].count('refused') == 2, final
        with pytest.raises(TimeoutError):
            tcp.accept()
        with pytest.raises(TimeoutError):
            udp.recvfrom(100)
    finally:
        tcp.close()
        udp.close()


def test_a_run_reaches_the_gateway_and_drives_where_its_starter_may(class_gw):
    run_id = started(class_gw, program('''
import os
rt.log("url " + os.environ["ROSBRIDGE_URL"].split("?")[0])
x0 = rt.latest("/s04/turtle1/pose", "turtlesim/msg/Pose", "x")
rt.drive("/s04/turtle1/cmd_vel", "geometry_msgs/msg/Twist", {"linear": {"x": 2.0}}, 1.0)
rt.sleep(0.3)
rt.log("moved %s" % (rt.latest("/s04/turtle1/pose", "turtlesim/msg/Pose", "x") > x0 + 0.5))
'''), '/s04')
    final = ended(class_gw, run_id, token=TOKENS['operator'])
    print(final['output'])
    assert final['state'] == 'finished', final
    assert f'url ws://127.0.0.1:{class_gw.port}/' in final['output'] and 'moved True' in final['output']


def test_run_user_is_never_root_and_warns_in_a_namespace_with_root_alone():
    """As root the runs' user is an unprivileged one; in a user namespace that maps uid 0 alone to
    the machine's root (unshare -r by root) there is none, and the gateway says so."""
    user = sandbox.run_user()
    if os.geteuid() != 0:
        assert user is None            # bwrap maps the run to this (unprivileged) uid
        pytest.skip('the rest needs root')
    assert user is not None and user[0] != 0 and user[1] != 0
    done = subprocess.run(['unshare', '-r', sys.executable, '-c',
                           'from gateway.runs.sandbox import run_user\nprint(run_user())'],
                          capture_output=True, text=True, timeout=60, cwd=Path(__file__).resolve().parents[2])
    assert done.stdout.strip() == 'None', done
    assert 'runs are uid 0 outside their box' in done.stderr and 'unshare -n' in done.stderr, done.stderr


def test_an_interpreter_the_runs_user_cannot_read_refuses_allow_runs(tmp_path, monkeypatch):
    closed = tmp_path / 'venv'
    (closed / 'bin').mkdir(parents=True)
    closed.chmod(0o700)
    assert unreadable(closed, 65534, 65534) is not None and unreadable(closed, os.stat(closed).st_uid, 0) is None
    assert not reachable(closed / 'bin' / 'python', 65534, 65534)
    if os.geteuid() != 0:
        pytest.skip('the gateway as root only: else the runs are the gateway\'s own uid')
    monkeypatch.setattr(sandbox, 'interpreter_paths', lambda: [closed])
    with pytest.raises(SandboxUnavailable) as refused:
        Sandbox.create(home=tmp_path)
    assert str(closed) in str(refused.value) and 'readable by others' in str(refused.value)
