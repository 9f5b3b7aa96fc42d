"""The ROS 2 nodes of the rover examples run in the IDE page (Chromium, `--robot rover`): the
wall-follower's node drives the simulated rover with its Twists and Stop ends it with a zero Twist,
saying why; the PID go-to-goal's node arrives and ends by itself. (The turtlesim examples:
tests/ide/test_rclpy_page.py; built and run on the Jazzy graph: tests/backends/test_ros_package.py.)"""

from __future__ import annotations

import time

import pytest

from tests.support.ide import IdePage
from tests.support.wait import wait_for

PYODIDE_START = 120


@pytest.fixture(scope='module')
def ide(chromium, rover_gateway):
    ctx = chromium.new_context(viewport={'width': 1400, 'height': 860})
    page = IdePage(ctx.new_page(), rover_gateway).open()
    yield page
    ctx.close()


def run_node_of(ide: IdePage, example: str):
    ide.load_example(example)
    code = ide.js('async () => rosgateIde.rosNode()')
    ide.js('(p) => rosgateIde.loadProgram(p)', {'format': 'rosgate-program', 'version': 1, 'kind': 'text',
                                                 'lang': 'python', 'name': example, 'text': code})
    ide.page.wait_for_function("document.body.dataset.connection === 'connected'", timeout=60000)
    ide.page.click('#run')
    ide.page.wait_for_function("document.body.dataset.run === 'running'")


def test_the_wall_followers_node_drives_the_rover_and_stop_zeroes_it(ide, rover_ros):
    cmd = rover_ros.watch('/cmd_vel', 'geometry_msgs/msg/Twist')
    run_node_of(ide, 'wall_follower.json')
    wait_for(lambda: len([m for _, m in cmd.messages if m['linear']['x'] or m['angular']['z']]) >= 10, PYODIDE_START,
             what='the node driving the rover')
    assert any(m['linear']['x'] in (0.3, 0.35) for _, m in cmd.messages)
    assert '[rover_wall_follower]: following the wall on the right' in ide.console_text()
    t0 = time.monotonic()
    ide.page.click('#stop')
    zero = wait_for(lambda: next((t for t, m in cmd.since(t0) if not m['linear']['x'] and not m['angular']['z']), None),
                    what='a zero Twist after Stop')
    ide.page.wait_for_function("document.body.dataset.run === 'idle'")
    time.sleep(0.5)
    assert all(not m['linear']['x'] and not m['angular']['z'] for _, m in cmd.since(zero + 0.05))
    assert 'stopped: Stop was pressed' in ide.console_text()


def test_the_pid_go_to_goals_node_arrives(ide):
    run_node_of(ide, 'pid_goal.json')
    ide.page.wait_for_function("document.body.dataset.run === 'idle'", timeout=PYODIDE_START * 1000)
    text = ide.console_text()
    assert '[rover_pid_go_to_goal]: arrived, distance left (cm): ' in text, text[-2000:]
    assert 'finished' in text.split('arrived')[-1]
