"""The Foxglove protocol against the rclpy gateway on a Jazzy graph: tests/node/foxglove.test.js, run
by node against two ``--backend rclpy`` gateways (one with --auth) on a graph with a turtle (an rclpy
node of its own context: /turtlesim integrating /turtle1/cmd_vel into /turtle1/pose) and the helper
nodes (/add_two_ints). The channels' schemas are what the install and the graph describe, the
messages the CDR the gateway took from DDS, handed to every Foxglove subscriber as taken."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from tests.support.auth import TOKENS
from tests.support.contract import rclpy_missing
from tests.support.ros import client
from tests.support.wait import wait_for

from .rclpy_nodes import OwnContextNode

ROOT = Path(__file__).resolve().parents[2]
NODE_DIR = ROOT / 'tests' / 'node'
POSE = 'geometry_msgs/msg/Pose2D'

pytestmark = [
    pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here'),
    pytest.mark.skipif(shutil.which('node') is None or not (NODE_DIR / 'node_modules' / '@foxglove').is_dir(),
                       reason='node or tests/node/node_modules (npm ci in tests/node) is missing'),
]


class Turtle(OwnContextNode):
    """/turtlesim: /turtle1/cmd_vel (Twist) moves it, /turtle1/pose (Pose2D) says where it is, 20 times
    a second; its parameter background_r is an integer, as turtlesim's."""

    def __init__(self):
        from geometry_msgs.msg import Pose2D, Twist
        super().__init__('turtlesim')
        self.pose, self.velocity, self.last = Pose2D(x=5.5, y=5.5), Twist(), time.monotonic()
        self.node.declare_parameter('background_r', 69)
        self.node.create_subscription(Twist, '/turtle1/cmd_vel', self._command, 10)
        self.publisher = self.node.create_publisher(Pose2D, '/turtle1/pose', 10)
        self.node.create_timer(0.05, self._step)
        self.start()

    def _command(self, twist) -> None:
        self.velocity = twist

    def _step(self) -> None:
        now = time.monotonic()
        dt, self.last = now - self.last, now
        p, v = self.pose, self.velocity
        p.theta += v.angular.z * dt
        p.x += v.linear.x * math.cos(p.theta) * dt
        p.y += v.linear.x * math.sin(p.theta) * dt
        self.publisher.publish(p)


@pytest.fixture(scope='module')
def turtle(rclpy_helpers):
    t = Turtle()
    yield t
    t.stop()


def test_foxglove_clients_on_the_jazzy_graph(turtle, rclpy_helpers, start_gateway, tokens_file):
    import roslibpy

    gateway = start_gateway('--backend', 'rclpy', '--history', 'none', '--send-buffer-limit', '262144', '--cmd-timeout', '0',
                            '--unregister-timeout', '0.5')
    locked = start_gateway('--backend', 'rclpy', '--history', 'none', '--auth', tokens_file, '--auth-timeout', '60')
    for gw, token in ((gateway, None), (locked, TOKENS['viewer'])):   # the turtle and the adder discovered first
        with client(gw, token=token) as ros:
            topics = roslibpy.Service(ros, '/rosapi/topics', 'rosapi_msgs/srv/Topics')
            services = roslibpy.Service(ros, '/rosapi/services', 'rosapi_msgs/srv/Services')
            wait_for(lambda: '/turtle1/pose' in topics.call(roslibpy.ServiceRequest({}), timeout=5)['topics']
                     and '/add_two_ints' in services.call(roslibpy.ServiceRequest({}), timeout=5)['services'],
                     timeout=20)
    env = {**os.environ, 'ROSGATE_URL': gateway.ws_url, 'ROSGATE_AUTH_URL': locked.ws_url,
           'ROSGATE_TOKENS': json.dumps({'operator': TOKENS['operator'], 'viewer': TOKENS['viewer']}),
           'ROSGATE_POSE_TYPE': POSE, 'ROSGATE_ADD_TYPE': rclpy_helpers.add_type}
    run = subprocess.run(['node', '--test', 'foxglove.test.js'], cwd=NODE_DIR, env=env, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-6000:] + run.stderr[-2000:]
    assert '# pass 15' in run.stdout and '# fail 0' in run.stdout, run.stdout[-4000:]
