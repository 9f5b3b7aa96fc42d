"""Run limits: the start-up line says exactly which limits hold a run, and by what (checked here
against the kernel's own files while a run goes), and the cgroup v2 path delegates controllers as
the kernel demands, exercised on this machine's real cgroup2 hierarchy (see below)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from gateway.runs.cgroups import LEAF, Cgroups, Scopes
from tests.support.http import api
from tests.support.process import ROOT
from tests.support.runs import RUNTIME, state_of
from tests.support.wait import wait_for

LINE = re.compile(r'runs: in a bwrap sandbox; run limits: (.*)')


@pytest.fixture(scope='module')
def runs_gw(start_gateway, tmp_path_factory):
    return start_gateway('--robot', 'none', '--allow-runs', '--runs-dir', str(tmp_path_factory.mktemp('runs')))


def test_the_start_up_line_says_which_limits_hold_and_the_kernel_agrees(runs_gw):
    line = wait_for(lambda: LINE.search(runs_gw.log_text()), 10).group(1)
    print(line)
    claims = {what: kind for what, kind in re.findall(r'(memory|processes|CPU) \S+(?: core\(s\))?(?: MiB)? by '
                                                      r'(cgroup v[12]) ', line)}
    cgroups, how = Cgroups.find()       # what this machine offers the gateway's user, asked again
    expected = {'memory': 'memory', 'processes': 'pids', 'CPU': 'cpu'}
    on = cgroups.controllers if cgroups else ()
    assert set(claims) == {what for what, c in expected.items() if c in on}, line
    unclaimed = {'memory': 'memory: only the', 'processes': 'processes: only RLIMIT_NPROC', 'CPU': 'CPU: no share limit'}
    for what, c in expected.items():
        assert (unclaimed[what] in line) == (c not in on), line
    assert 'CPU time 600 s by RLIMIT_CPU' in line and 'open files 256 by RLIMIT_NOFILE' in line
    if not cgroups:
        return
    # a run in progress: each claimed limit is in the kernel's file of the run's own cgroup
    source = f'{RUNTIME}\n\ndef main():\n    rt.sleep(60)\n\nif __name__ == "__main__":\n    run(main)\n'
    status, body = api(runs_gw, 'POST', '/api/runs', {'source': source, 'ns': '/'})
    assert status == 201, body
    run_id = body['id']
    try:
        name = f'rosgate-{runs_gw.pid}-{run_id}'
        files = {'v2': {'memory': ('memory.max', str(2**30)), 'pids': ('pids.max', '512'),
                        'cpu': ('cpu.max', '100000 100000')},
                 'v1': {'memory': ('memory.limit_in_bytes', str(2**30)), 'pids': ('pids.max', '512'),
                        'cpu': ('cpu.cfs_quota_us', '100000')}}
        for controller, parent in cgroups.parents:
            d = parent / name
            wait_for(lambda: (d / 'cgroup.procs').exists() and (d / 'cgroup.procs').read_text().split(), 30)
            kind = 'v2' if controller == 'v2' else 'v1'
            for c in (cgroups.controllers if kind == 'v2' else (controller,)):
                file, value = files[kind][c]
                assert (d / file).read_text().strip() == value, (d / file)
    finally:
        api(runs_gw, 'DELETE', f'/api/runs/{run_id}')
        wait_for(lambda: state_of(runs_gw, run_id)['state'] != 'running', 30)


# --- cgroup v2, on the kernel -------------------------------------------------------------------
# This machine mounts cgroup v1 hierarchies for memory, pids and cpu, and cgroup2 at
# /sys/fs/cgroup/unified with one controller of its own, hugetlb. A controller is bound to one
# hierarchy, so memory, pids and cpu cannot be tried in cgroup2 here; the delegation itself can:
# the kernel's "no internal processes" rule (EBUSY on +controller while the cgroup holds a
# process) applies to hugetlb as to memory. These tests move a child process of their own into
# a cgroup made for them, and remove it after.

UNIFIED = Path('/sys/fs/cgroup/unified')


def cgroup2_with_hugetlb() -> bool:
    try:
        mounts = Path('/proc/mounts').read_text().split('\n')
        return any(f' {UNIFIED} cgroup2 ' in f' {m}' for m in mounts) and \
            'hugetlb' in (UNIFIED / 'cgroup.controllers').read_text().split() and os.access(UNIFIED, os.W_OK)
    except OSError:
        return False


needs_cgroup2 = pytest.mark.skipif(not cgroup2_with_hugetlb(), reason='no writable cgroup2 mount with hugetlb here')

FIND = '''import json, os, sys
from pathlib import Path
from gateway.runs.cgroups import Cgroups
service = Path(sys.argv[1])
(service / "cgroup.procs").write_text(str(os.getpid()))   # where a service manager would start it
cgroups, how = Cgroups.find(Path(sys.argv[2]), want=("hugetlb",), need=("hugetlb",))
print(json.dumps({"how": how, "found": cgroups is not None,
                  "controllers": list(cgroups.controllers) if cgroups else [],
                  "own": Path("/proc/self/cgroup").read_text()}))
'''


@pytest.fixture
def service():
    """A cgroup under the cgroup2 root, standing for the gateway's service cgroup (Delegate=yes)."""
    root_on = (UNIFIED / 'cgroup.subtree_control').read_text().split()
    if 'hugetlb' not in root_on:       # the root cgroup may enable it whatever it holds
        (UNIFIED / 'cgroup.subtree_control').write_text('+hugetlb')
    d = UNIFIED / f'rosgate-test-{os.getpid()}'
    d.mkdir()
    others: list[subprocess.Popen] = []
    yield d, others
    for p in others:
        p.kill()
        p.wait()
    for sub in sorted(d.rglob('*'), reverse=True):
        if sub.is_dir():
            wait_for(lambda: not (sub / 'cgroup.procs').read_text().split(), 10)
            sub.rmdir()
    wait_for(lambda: not (d / 'cgroup.procs').read_text().split(), 10)
    (d / 'cgroup.subtree_control').write_text('-hugetlb') if 'hugetlb' in \
        (d / 'cgroup.subtree_control').read_text().split() else None
    d.rmdir()
    if 'hugetlb' not in root_on:
        (UNIFIED / 'cgroup.subtree_control').write_text('-hugetlb')


def find_in(service_dir: Path) -> dict:
    done = subprocess.run([sys.executable, '-c', FIND, str(service_dir), str(UNIFIED)], capture_output=True,
                          text=True, timeout=60, cwd=ROOT, env={**os.environ, 'PYTHONPATH': str(ROOT)})
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


@needs_cgroup2
def test_the_kernel_refuses_controllers_to_a_cgroup_that_holds_a_process(service):
    d, others = service
    sleeper = subprocess.Popen(['sleep', '600'])
    others.append(sleeper)
    (d / 'cgroup.procs').write_text(str(sleeper.pid))
    with pytest.raises(OSError) as refused:
        (d / 'cgroup.subtree_control').write_text('+hugetlb')
    assert refused.value.errno == 16   # EBUSY: what writing +memory into the gateway's own cgroup met


@needs_cgroup2
def test_the_gateway_moves_itself_into_a_leaf_then_enables_the_controllers(service):
    d, _ = service
    found = find_in(d)
    assert found['found'] and found['controllers'] == ['hugetlb'], found
    assert f'moved itself into {d / LEAF}' in found['how'], found['how']
    assert f'0::/{d.name}/{LEAF}' in found['own']                         # the kernel moved it
    assert (d / 'cgroup.subtree_control').read_text().split() == ['hugetlb']   # and enabled it
    run = d / 'rosgate-run-probe'
    run.mkdir()                                                          # a run's cgroup has it
    assert (run / 'hugetlb.2MB.max').exists() or any(run.glob('hugetlb.*.max'))


@needs_cgroup2
def test_a_cgroup_shared_with_other_processes_is_reported_not_taken(service):
    d, others = service
    sleeper = subprocess.Popen(['sleep', '600'])
    others.append(sleeper)
    (d / 'cgroup.procs').write_text(str(sleeper.pid))                     # a login shell's scope, say
    found = find_in(d)
    assert not found['found'], found
    assert 'holds 1 other process(es)' in found['how'] and 'hugetlb' in found['how'], found['how']
    assert not (d / LEAF).exists()


# --- systemd scopes -----------------------------------------------------------------------------

def test_systemd_scopes_only_where_systemd_runs_and_shows_the_limits():
    """On the machine itself: systemd is not the init here, and the sentence says so; where it
    is, a probe scope must show memory and pids limits in its own cgroup files."""
    scopes, how = Scopes.find()
    if not Path('/run/systemd/system').is_dir():
        assert scopes is None and how == 'systemd is not running here (/run/systemd/system is missing)'
    else:
        assert (scopes is not None and {'memory', 'pids'} <= set(scopes.controllers)) or 'systemd-run' in how, how


def test_a_run_scope_command_file_logic():
    """Pure logic: the command a run starts with under systemd (systemd-run execs it in the scope)."""
    scope = Scopes(('/usr/bin/systemd-run',), ('memory', 'pids', 'cpu')).make('r0123abcd', 2**30, 512, 0.5)
    argv = scope.join(['bwrap', '--', 'python'])
    assert argv[:5] == ['/usr/bin/systemd-run', '--scope', '--quiet', '--collect', f'--unit=rosgate-{os.getpid()}-r0123abcd']
    props = [argv[i + 1] for i, a in enumerate(argv) if a == '-p']
    assert props == [f'MemoryMax={2**30}', 'MemorySwapMax=0', 'TasksMax=512', 'CPUQuota=50%']
    assert argv[argv.index('--'):] == ['--', 'bwrap', '--', 'python']
