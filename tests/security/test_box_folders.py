"""The runs' box folders (/tmp/rosgate-box-*: the unix socket a run reaches its gateway by) belong to
their gateway by a lock it holds while it lives, not by the PID in their name: a gateway started in
another PID namespace on the same /tmp saw none of its neighbour's PIDs and deleted its live folder
(its runs then failed with exit 125, "mount point does not exist", until it restarted)."""

from __future__ import annotations

import os
import signal
import sys
import tempfile
from pathlib import Path

from tests.support.http import api
from tests.support.process import ROOT, Started
from tests.support.wait import wait_for

PROGRAM = 'print("the box still works", flush=True)\n'


def box_folders(pid: int) -> list[Path]:
    return sorted(Path(tempfile.gettempdir()).glob(f'rosgate-box-{pid}-*'))


def run_ends_well(gw) -> dict:
    status, run = api(gw, 'POST', '/api/runs', {'source': PROGRAM})
    assert status == 201, run
    done = wait_for(lambda: (lambda r: r if r['state'] not in ('starting', 'running') else None)(
        api(gw, 'GET', f"/api/runs/{run['id']}")[1]), 60, 0.1, what='the run ended')
    assert done['exit_code'] == 0 and 'the box still works' in done['output'], done
    return done


def gateway_in_own_pid_namespace(tmp: Path) -> Started:
    """A gateway with --allow-runs as a container would start it: a PID namespace (and /proc) of its
    own, the machine's /tmp."""
    return Started(['unshare', '--pid', '--fork', '--kill-child', '--mount-proc', sys.executable, '-m', 'gateway', '--port', '0',
                    '--address', '127.0.0.1', '--allow-runs', '--programs-dir', str(tmp / 'programs'),
                    '--runs-dir', str(tmp / 'runs')], cwd=ROOT,
                   env={**os.environ, 'XDG_DATA_HOME': str(tmp / 'data')}, timeout=60)


def test_a_gateway_in_another_pid_namespace_leaves_a_live_gateways_box_folder(launch, tmp_path):
    first = launch('--allow-runs')
    mine = box_folders(first.pid)
    assert len(mine) == 1, mine
    neighbour = gateway_in_own_pid_namespace(tmp_path / 'neighbour')
    try:
        assert mine[0].is_dir(), 'the neighbour swept a live gateway\'s box folder'
        run_ends_well(first)
    finally:
        neighbour.stop()


def test_a_dead_gateways_box_folder_is_swept_by_the_next(launch, tmp_path):
    before = set(Path(tempfile.gettempdir()).glob('rosgate-box-*'))
    dead = gateway_in_own_pid_namespace(tmp_path / 'dead')
    # its folder is named by its pid in its own namespace (1); other test processes make theirs meanwhile
    theirs = set(Path(tempfile.gettempdir()).glob('rosgate-box-1-*')) - before
    assert len(theirs) == 1, theirs
    dead.stop(signal.SIGKILL)      # killed (its namespace with it): nothing of its own cleaned up
    assert next(iter(theirs)).is_dir()
    alive = launch('--allow-runs')
    assert not next(iter(theirs)).exists(), 'the killed gateway\'s folder was not swept'
    assert box_folders(alive.pid)
    run_ends_well(alive)
