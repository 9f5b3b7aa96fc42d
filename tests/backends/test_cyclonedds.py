"""Across DDS vendors: a robot on Eclipse Cyclone DDS (no ROS, the cyclonedds binding by hand),
a roslibpy client through the gateway on Fast DDS (rclpy backend). Topics both ways.

What this cannot show: services across vendors (a hand-written Cyclone participant does not
serve ROS 2 request/reply topics the way rmw_cyclonedds_cpp does), nor a robot running
rmw_cyclonedds_cpp itself, which has no PyPI build.
"""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

import pytest

from tests.support.contract import rclpy_missing
from tests.support.wait import wait_for

ROOT = Path(__file__).resolve().parents[2]
pytestmark = [
    pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here'),
    pytest.mark.timeout(120),
]


@pytest.fixture
def cyclone_robot(rclpy_helpers):
    pytest.importorskip('cyclonedds', reason='cyclonedds is installed by make test-rclpy')
    proc = subprocess.Popen([sys.executable, '-m', 'tests.backends.cyclone_robot', '90'], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, '')), daemon=True)
    reader.start()
    wait_for(lambda: 'ready\n' in lines or proc.poll() is not None, timeout=30)
    assert proc.poll() is None, ''.join(lines)
    yield lines
    proc.kill()
    proc.wait()


def test_topics_both_ways_with_a_cyclone_dds_robot(rclpy_helpers, start_gateway, cyclone_robot):
    import roslibpy

    gateway = start_gateway('--backend', 'rclpy')
    ros = roslibpy.Ros(host=gateway.host, port=gateway.port)
    ros.run(timeout=20)
    try:
        heard: list[str] = []
        chatter = roslibpy.Topic(ros, '/cyclone/chatter', 'std_msgs/msg/String')
        chatter.subscribe(lambda msg: heard.append(msg['data']))
        wait_for(lambda: len(heard) >= 3, timeout=30)
        assert all(text.startswith('hello ') for text in heard)
        numbers = [int(text.split()[1]) for text in heard[:3]]
        assert numbers == sorted(numbers)

        echo = roslibpy.Topic(ros, '/cyclone/echo', 'std_msgs/msg/String')
        echo.advertise()

        def received() -> bool:
            echo.publish(roslibpy.Message({'data': 'from rosgate'}))
            return 'got from rosgate\n' in cyclone_robot

        wait_for(received, timeout=30, interval=0.2)
    finally:
        ros.close()
