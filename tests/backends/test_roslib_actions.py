"""npm roslib's Action against the rclpy gateway on a Jazzy graph: tests/node/actions.test.js, run by
node against a ``--backend rclpy`` gateway whose Fibonacci server is the helper nodes' (an rclpy
ActionServer), so ``cancelAllGoals()`` goes through a real ``_action/cancel_goal`` service."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.support.ros import client
from tests.support.wait import wait_for

from tests.support.contract import rclpy_missing

ROOT = Path(__file__).resolve().parents[2]
NODE_DIR = ROOT / 'tests' / 'node'

pytestmark = [
    pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here'),
    pytest.mark.skipif(shutil.which('node') is None or not (NODE_DIR / 'node_modules' / 'roslib').is_dir(),
                       reason='node or tests/node/node_modules (npm ci in tests/node) is missing'),
]


def test_roslib_cancel_all_goals_and_a_mistyped_goal_on_the_jazzy_graph(rclpy_helpers, start_gateway):
    import roslibpy

    gateway = start_gateway('--backend', 'rclpy')
    with client(gateway) as ros:   # the helper nodes' /fibonacci discovered by the gateway first
        servers = roslibpy.Service(ros, '/rosapi/action_servers', 'rosapi_msgs/srv/GetActionServers')
        wait_for(lambda: '/fibonacci' in servers.call(roslibpy.ServiceRequest({}), timeout=5)['action_servers'],
                 timeout=15)
    env = {**os.environ, 'ROSGATE_URL': gateway.ws_url, 'ROSGATE_FIB_TYPE': rclpy_helpers.fib_type}
    run = subprocess.run(['node', '--test', 'actions.test.js'], cwd=NODE_DIR, env=env, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert '# pass 3' in run.stdout and '# fail 0' in run.stdout, run.stdout[-4000:]
