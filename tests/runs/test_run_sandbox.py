"""Runs in their sandbox, against a gateway started as a class would (``--auth --allow-runs
--exclusive-control --fleet 12``): what a run can reach, how it ends, and how many may go."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid

import pytest

from gateway.runs.cgroups import Cgroups
from gateway.runs.sandbox import Sandbox
from gateway.runs.supervisor import LAUNCHER
from tests.support.auth import ROSAUTH_SECRET, TOKENS, tokens_toml
from tests.support.http import api
from tests.support.runs import alive, ended, state_of
from tests.support.wait import wait_for

SECRET = 'gateway-env-secret-5f6e'
ADMIN = TOKENS['admin']

# Forks, setsids, forks again and ignores SIGINT, SIGTERM and SIGHUP: the grandchild is in a
# session and process group of its own. Every process of it carries MARKER in its command line.
ESCAPER = '''import os, signal, sys, time
MARKER = {marker!r}
for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
    signal.signal(s, signal.SIG_IGN)
if MARKER not in sys.argv:
    os.execv(sys.executable, [sys.executable, "-u", __file__, MARKER])
if os.fork() == 0:
    os.setsid()
    if os.fork() == 0:
        os.execv(sys.executable, [sys.executable, "-c", "import time\\nwhile True: time.sleep(0.2)", MARKER])
    os._exit(0)
os.wait()
print("escaped", flush=True)
while True:
    time.sleep(0.2)
'''


@pytest.fixture(scope='module')
def class_gw(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('class')
    (folder / 'tokens.toml').write_text(tokens_toml())
    gw = start_gateway('--robot', 'turtlesim', '--fleet', '12', '--allow-runs', '--exclusive-control',
                       '--runs-dir', str(folder / 'runs'), '--auth', str(folder / 'tokens.toml'),
                       env={'ROSGATE_TEST_SECRET': SECRET})
    gw.tokens_path = folder / 'tokens.toml'
    return gw


@pytest.fixture
def marker():
    """A text to find a run's processes by; those still alive after the test are killed."""
    text = f'escaper-{uuid.uuid4().hex}'
    yield text
    for pid in alive(text):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def post(gw, source: str, ns: str, token: str = ADMIN, **kw):
    return api(gw, 'POST', '/api/runs', {'source': source, 'ns': ns, 'name': 'sandbox test', **kw}, token=token)


def started(gw, source: str, ns: str, token: str = ADMIN, **kw) -> str:
    status, body = post(gw, source, ns, token, **kw)
    assert status == 201, body
    return body['id']


def output_has(gw, run_id: str, text: str, timeout: float = 60) -> dict:
    return wait_for(lambda: (lambda b: b if text in b['output'] else None)(state_of(gw, run_id, ADMIN)), timeout, 0.02)


def cpu_seconds(pid: int) -> float:
    fields = open(f'/proc/{pid}/stat').read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def test_an_escaped_grandchild_is_gone_2_5_s_after_delete(class_gw, marker):
    run_id = started(class_gw, ESCAPER.format(marker=marker), '/s01')
    output_has(class_gw, run_id, 'escaped')
    assert len(wait_for(lambda: (lambda p: p if len(p) >= 2 else None)(alive(marker)), 10)) >= 2
    sent = time.monotonic()
    status, body = api(class_gw, 'DELETE', f'/api/runs/{run_id}', token=ADMIN)
    assert status == 202, body
    wait_for(lambda: not alive(marker), 2.5 - (time.monotonic() - sent), 0.02)
    assert ended(class_gw, run_id, token=ADMIN)['state'] == 'stopped'


def test_an_escaped_grandchild_is_gone_2_5_s_after_the_timeout(class_gw, marker):
    run_id = started(class_gw, ESCAPER.format(marker=marker), '/s02', timeout=1)
    output_has(class_gw, run_id, 'escaped')
    seen = time.monotonic()            # the run's timer started before its first output
    assert len(alive(marker)) >= 2
    wait_for(lambda: not alive(marker), 1 + 2.5 - (time.monotonic() - seen), 0.02)
    assert ended(class_gw, run_id, token=ADMIN)['state'] == 'timed_out'


def test_the_whole_run_dies_with_the_gateway(start_gateway, tmp_path, marker):
    gw = start_gateway('--robot', 'turtlesim', '--allow-runs', '--runs-dir', str(tmp_path))
    run_id = started(gw, ESCAPER.format(marker=marker), '')
    output_has(gw, run_id, 'escaped')
    assert alive(marker)
    gw.proc.kill()                     # no shutdown of its own: only --die-with-parent is left
    gw.proc.wait(10)
    wait_for(lambda: not alive(marker), 2.5, 0.02)


SNOOP = '''import os, sys
def show(what, path, binary=False):
    try:
        with open(path, "rb") as f:
            print(what, path, f.read().replace(b"\\0", b" ").decode("utf-8", "replace"))
    except OSError as e:
        print(what, path, "->", type(e).__name__)
print("environ", dict(os.environ))
pids = sorted(int(p) for p in os.listdir("/proc") if p.isdigit())
print("pids", pids)
for pid in pids:
    show("cmdline", f"/proc/{pid}/cmdline")
    show("environ", f"/proc/{pid}/environ")
show("gateway cmdline", "/proc/%d/cmdline" % GATEWAY)
show("gateway environ", "/proc/%d/environ" % GATEWAY)
show("tokens", TOKENS_FILE)
for d in ["/", "/root", "/home", "/home/run", "/tmp", "/etc", "/work", RUNS, HOME]:
    try:
        print("ls", d, sorted(os.listdir(d)))
    except OSError as e:
        print("ls", d, "->", type(e).__name__)
for dirpath, dirs, files in os.walk("/"):     # files besides the system's and the interpreter's
    if dirpath.startswith(("/proc", "/usr", "/sys", "/dev", sys.prefix, sys.base_prefix)):
        dirs.clear()
        continue
    for name in files:
        if name.endswith((".toml", ".json", ".mcap", ".pem", ".key")) and not dirpath.startswith("/etc/ssl"):
            show("found", os.path.join(dirpath, name))
print("done")
'''


def test_a_run_sees_nothing_of_the_gateway(class_gw):
    source = (f'GATEWAY = {class_gw.pid}\nTOKENS_FILE = {str(class_gw.tokens_path)!r}\n'
              f'RUNS = {str(class_gw.tokens_path.parent / "runs")!r}\nHOME = {os.path.expanduser("~")!r}\n' + SNOOP)
    run_id = started(class_gw, source, '/s03')
    body = ended(class_gw, run_id, token=ADMIN)
    output = body['output']
    print(output)
    assert body['state'] == 'finished' and 'done' in output, body
    for secret in (*TOKENS.values(), ROSAUTH_SECRET, SECRET):
        assert secret not in output
    tried = output.replace(str(class_gw.tokens_path.parent / 'runs'), 'RUNS').replace(str(class_gw.tokens_path),
                                                                                      'TOKENS_FILE')
    for part in ('--exclusive-control', '--auth', '--fleet', str(class_gw.tokens_path.parent)):
        assert part not in tried, part          # nothing of the gateway's command line
    assert 'tokens TOKENS_FILE -> FileNotFoundError' in tried and 'ls RUNS -> FileNotFoundError' in tried
    pids = json.loads(output.split('pids ', 1)[1].split('\n', 1)[0])
    assert pids[:2] == [1, 2] and len(pids) == 3, pids     # bwrap's init, the program and its relay
    assert f'cmdline /proc/{pids[2]}/cmdline {sys.executable} -I -c {LAUNCHER.splitlines()[0]}' in output
    assert f'gateway cmdline /proc/{class_gw.pid}/cmdline -> FileNotFoundError' in output


def test_namespaces_are_those_of_the_graph(class_gw):
    for ns, status in (('/ｓ01', 400), ('/s' + '0' * 5000, 400), ('/s' + '1' * 300, 400), ('/s99', 404),
                       ('/s01/../s02', 400), ('/S01', 404)):
        code, body = post(class_gw, 'print(1)', ns)
        assert code == status, (ns[:20], body)
        assert 'namespace' in body['error'] and len(body['error']) < 600, body
    run_id = started(class_gw, 'print("in s04")', 's04/')      # written loosely, still a station
    assert state_of(class_gw, run_id, ADMIN)['ns'] == '/s04'
    assert ended(class_gw, run_id, token=ADMIN)['state'] == 'finished'


def stop_all(gw, ids) -> None:
    for run_id in ids:
        api(gw, 'DELETE', f'/api/runs/{run_id}', token=ADMIN)
    for run_id in ids:
        ended(gw, run_id, token=ADMIN)


def test_at_most_max_runs_go_at_once_and_each_of_them_runs(class_gw):
    accepted, refused = {}, []
    try:
        for i in range(1, 13):
            status, body = post(class_gw, 'import time\nprint("running", flush=True)\ntime.sleep(60)', f'/s{i:02d}')
            if status == 201:
                accepted[body['id']] = i
            else:
                refused.append((status, body['error']))
        assert len(accepted) == 4, refused
        assert all(s == 429 and '--max-runs' in e for s, e in refused) and len(refused) == 8, refused
        for run_id in accepted:
            assert output_has(class_gw, run_id, 'running')['state'] == 'running'
    finally:
        stop_all(class_gw, accepted)
    status, body = post(class_gw, 'print("again")', '/s12')      # room again once they ended
    assert status == 201, body
    ended(class_gw, body['id'], token=ADMIN)


def test_one_person_has_at_most_max_runs_per_person(class_gw):
    sleeper = 'import time\nprint("running", flush=True)\ntime.sleep(60)'
    ids = []
    try:
        for ns in ('/s05', '/s06'):
            ids.append(started(class_gw, sleeper, ns, TOKENS['operator']))
        status, body = post(class_gw, sleeper, '/s07', TOKENS['operator'])
        assert status == 429 and 'alice' in body['error'] and '--max-runs-per-person' in body['error'], body
        ids.append(started(class_gw, sleeper, '/s07', TOKENS['operator2']))    # bob is someone else
        for run_id in ids:
            assert output_has(class_gw, run_id, 'running')['state'] == 'running'
    finally:
        stop_all(class_gw, ids)


def test_an_output_flood_costs_the_gateway_little_cpu(class_gw):
    # 64 KiB of short lines per write: cheap for the program, a lot of lines for whoever splits them
    run_id = started(class_gw, 'import sys\nblock = ("y" * 15 + "\\n") * 4096\nwhile True:\n    sys.stdout.write(block)\n',
                     '/s08')
    try:
        output_has(class_gw, run_id, 'output limit of')
        before, at = cpu_seconds(class_gw.pid), time.monotonic()
        wait_for(lambda: time.monotonic() - at >= 5, 6, 0.1)       # the flood goes on meanwhile
        share = (cpu_seconds(class_gw.pid) - before) / (time.monotonic() - at)
        print(f'gateway CPU over 5 s of flood past the cap: {share:.1%} of a core')
        assert share <= 0.25
        assert state_of(class_gw, run_id, ADMIN)['state'] == 'running'
    finally:
        stop_all(class_gw, [run_id])


def test_allow_runs_without_bwrap_refuses_to_start_naming_the_package(tmp_path):
    done = subprocess.run([sys.executable, '-m', 'gateway', '--port', '0', '--address', '127.0.0.1', '--allow-runs',
                           '--runs-dir', str(tmp_path)], capture_output=True, text=True, timeout=60,
                          env={**os.environ, 'PATH': str(tmp_path)})
    assert done.returncode != 0
    assert 'bubblewrap' in done.stderr and '--allow-runs' in done.stderr, done.stderr[-2000:]


def test_cgroup_v2_run_cgroups_file_logic(tmp_path):
    """File logic only, on a folder laid out like /sys/fs/cgroup in v2: which files a run cgroup
    gets and what they hold. Plain files accept any write, unlike the kernel; the kernel's rules
    (EBUSY, the leaf the gateway moves into) are tried on a real cgroup2 in test_run_limits.py."""
    own = tmp_path / 'system.slice' / 'rosgate.service'
    own.mkdir(parents=True)
    (tmp_path / 'cgroup.controllers').write_text('cpu memory pids\n')
    (own / 'cgroup.controllers').write_text('cpu memory pids\n')
    (own / 'cgroup.subtree_control').write_text('memory pids\n')
    cgroups, how = Cgroups.find(tmp_path, '0::/system.slice/rosgate.service\n')
    assert cgroups is not None and how == f'cgroup v2 limits (memory, pids, cpu) in {own}', how
    assert (own / 'cgroup.subtree_control').read_text() == '+cpu'      # the one that was off, asked for
    run = cgroups.make('r0123abcd', 2**30, 512, 1.0)
    d = own / f'rosgate-{os.getpid()}-r0123abcd'
    assert run.dirs == (d,)
    assert (d / 'memory.max').read_text() == str(2**30) and (d / 'pids.max').read_text() == '512'
    assert (d / 'cpu.max').read_text() == '100000 100000'
    assert run.join(['bwrap'])[-2:] == ['--', 'bwrap'] and str(d / 'cgroup.procs') in run.join(['bwrap'])
    assert not run.oom_killed()
    (d / 'memory.events').write_text('low 0\nhigh 0\nmax 3\noom 1\noom_kill 1\n')
    assert run.oom_killed()


def test_cgroup_v2_controllers_not_delegated_file_logic(tmp_path):
    """File logic only: a cgroup whose cgroup.controllers lacks memory (never delegated to it)
    gives no run cgroups, and the sentence says how to start the gateway instead."""
    own = tmp_path / 'user.slice'
    own.mkdir()
    (tmp_path / 'cgroup.controllers').write_text('cpu memory pids\n')
    (own / 'cgroup.controllers').write_text('cpu pids\n')
    cgroups, how = Cgroups.find(tmp_path, '0::/user.slice\n')
    assert cgroups is None and 'memory not delegated' in how and 'Delegate=yes' in how, how


def test_an_interpreter_under_tmp_is_seen_over_the_private_tmp():
    """A checkout (and its venv) under /tmp: the run's private /tmp is made first, and the
    interpreter's folders are bound over it (the other way round the venv would be hidden)."""
    box = Sandbox('bwrap', ('--ro-bind', '/tmp/ci/.venv', '/tmp/ci/.venv'), (), 0)
    argv = box.argv(['python'])
    assert argv.index('/tmp') < argv.index('/tmp/ci/.venv')
