"""A block program downloaded from the IDE (Chromium) as a ROS 2 package: it builds with colcon
against the Jazzy wheels and, run as a node on the graph, sends a robot node the same Twists as the
roslibpy script of the same program run through the gateway (rclpy backend); Ctrl-C ends both with
zero velocity.

Run inside a loopback-only network namespace, as ``make test-rclpy`` does.
"""

from __future__ import annotations

import io
import math
import os
import signal
import subprocess
import sys
import threading
import zipfile
from pathlib import Path

import pytest

from tests.support.contract import rclpy_missing
from tests.support.ide import IdePage
from tests.support.wait import wait_for

pytestmark = [pytest.mark.skipif(rclpy_missing() is not None, reason=f'rclpy does not import: {rclpy_missing()}'),
              pytest.mark.timeout(400)]

BIN = Path(sys.executable).parent
EXAMPLE = 'wall_follower.json'
PHASE = 5          # Twists heard in each phase of the robot's scan


class Rover:
    """A rover driver in a context of its own: a 360-ray /scan with a wall on the right (0.6 m),
    and, once it has heard PHASE Twists, a wall ahead (0.5 m) too; records each Twist heard."""

    def __init__(self):
        import rclpy
        from geometry_msgs.msg import Twist
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        from sensor_msgs.msg import LaserScan
        self.context = Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('rover', context=self.context)
        self.heard: list[tuple[float, float]] = []
        self.start = 0
        self.node.create_subscription(Twist, '/cmd_vel', lambda m: self.heard.append(
            (round(m.linear.x, 6), round(m.angular.z, 6))), 100)
        scan_pub = self.node.create_publisher(LaserScan, '/scan', 10)

        def scan():
            msg = LaserScan(angle_min=-math.pi, angle_max=math.pi, angle_increment=2 * math.pi / 360,
                            range_min=0.1, range_max=10.0)
            ranges = [5.0] * 360
            for i in range(75, 106):                # -105..-75 degrees: the wall on the right
                ranges[i] = 0.6
            if len(self.heard) - self.start >= PHASE:
                for i in range(165, 196):           # -15..15 degrees: a wall ahead
                    ranges[i] = 0.5
            msg.ranges = ranges
            scan_pub.publish(msg)

        self.node.create_timer(0.02, scan)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        try:
            self.executor.spin()
        except Exception:     # the context shut down under it
            pass

    def begin(self):
        self.start = len(self.heard)

    def sequence(self) -> list[tuple[float, float]]:
        """The Twists heard since begin(), repeats collapsed."""
        out = []
        for tw in self.heard[self.start:]:
            if not out or out[-1] != tw:
                out.append(tw)
        return out

    def stop(self):
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()
        self.thread.join(5)


@pytest.fixture(scope='module')
def rover(rclpy_helpers):
    r = Rover()
    yield r
    r.stop()


@pytest.fixture(scope='module')
def from_ide(chromium, start_gateway):
    """The example's ROS 2 package (the .zip the IDE's download gives) and its roslibpy script."""
    gw = start_gateway('--robot', 'rover')
    ctx = chromium.new_context(accept_downloads=True)
    ide = IdePage(ctx.new_page(), gw).open()
    ide.load_example(EXAMPLE)
    script = ide.python()
    node_panel = ide.js("document.querySelector('#code-node').textContent")
    with ide.page.expect_download() as download:
        ide.page.click('#download-ros2')
    data = Path(download.value.path()).read_bytes()
    name = download.value.suggested_filename
    assert not ide.errors, ide.errors
    ctx.close()
    return name, data, script, node_panel


def drive(rover, proc: subprocess.Popen) -> tuple[list, str]:
    """Lets the program drive through both phases, then Ctrl-C; the Twists the rover heard."""
    try:
        wait_for(lambda: len(rover.heard) - rover.start >= 2 * PHASE + 3, 60)
    finally:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=30)
    wait_for(lambda: rover.heard[-1] == (0.0, 0.0), 10)
    return rover.sequence(), out


def test_the_package_builds_and_drives_as_the_script_does(rover, from_ide, start_gateway, tmp_path):
    name, data, script, node_panel = from_ide
    assert name == 'rover wall-follower.zip'
    pkg = 'rover_wall_follower'
    node = f'{pkg}_node'
    archive = zipfile.ZipFile(io.BytesIO(data))
    files = set(archive.namelist())
    for f in ('package.xml', 'setup.py', 'setup.cfg', f'resource/{pkg}', f'{pkg}/__init__.py', f'{pkg}/{node}.py',
              f'{pkg}/rosgate_node.py', f'{pkg}/rosgate_runtime.py', 'README.md'):
        assert f'{pkg}/{f}' in files, files
    xml = archive.read(f'{pkg}/package.xml').decode()
    for dep in ('rclpy', 'geometry_msgs', 'sensor_msgs'):
        assert f'<exec_depend>{dep}</exec_depend>' in xml
    readme = archive.read(f'{pkg}/README.md').decode()
    assert 'colcon build' in readme and f'ros2 run {pkg} {node}' in readme
    code = archive.read(f'{pkg}/{pkg}/{node}.py').decode()
    assert code == node_panel                    # the code panel shows the node the package carries
    assert "self.publisher('cmd_vel', Twist)" in code and "self.subscription('scan', LaserScan)" in code

    (tmp_path / 'src').mkdir()
    archive.extractall(tmp_path / 'src')
    env = {**os.environ, 'PATH': f'{BIN}{os.pathsep}{os.environ.get("PATH", "/usr/bin")}'}
    built = subprocess.run([str(BIN / 'colcon'), 'build'], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert built.returncode == 0, built.stdout[-3000:] + built.stderr[-3000:]
    entry = tmp_path / 'install' / pkg / 'lib' / pkg / node
    site = next((tmp_path / 'install' / pkg / 'lib').glob('python3*/site-packages'))
    assert entry.exists()

    # the roslibpy script through a gateway on the graph
    gw = start_gateway('--backend', 'rclpy')
    (tmp_path / 'script.py').write_text(script)
    rover.begin()
    proc = subprocess.Popen([sys.executable, str(tmp_path / 'script.py'), '--url', gw.ws_url],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    by_script, out = drive(rover, proc)
    print('script:', by_script, out[-500:])

    # the node, run as `ros2 run` would: the installed entry point with the install's Python path
    rover.begin()
    proc = subprocess.Popen([sys.executable, str(entry)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**env, 'PYTHONPATH': f'{site}{os.pathsep}{os.environ.get("PYTHONPATH", "")}'})
    by_node, out = drive(rover, proc)
    print('node:', by_node, out[-500:])
    assert proc.returncode == 0, out
    expected = [(0.35, 0.0), (0.0, round(math.radians(60), 6)), (0.0, 0.0)]
    assert by_script == expected
    assert by_node == expected
