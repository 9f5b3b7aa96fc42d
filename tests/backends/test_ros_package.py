"""A block program downloaded from the IDE (Chromium) as a ROS 2 package: its node is plain rclpy
(no runtime beside it); it builds with colcon against the Jazzy wheels and, run as a node on the
graph, sends a robot node the same Twists as the roslibpy script of the same program run through
the gateway (rclpy backend); Ctrl-C ends both with zero velocity. The server blocks, in the node,
answer a roslibpy service call and an action goal through the gateway. With --trusted-runs the
gateway runs the node as a run of the graph.

Run inside a loopback-only network namespace, as ``make test-rclpy`` does.
"""

from __future__ import annotations

import io
import math
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from tests.support.contract import rclpy_missing
from tests.support.http import api
from tests.support.ide import IdePage
from tests.support.ros import client
from tests.support.runs import ended
from tests.support.servers import check_served, program
from tests.support.wait import wait_for

from .rclpy_nodes import OwnContextNode

pytestmark = [pytest.mark.skipif(rclpy_missing() is not None, reason=f'rclpy does not import: {rclpy_missing()}'),
              pytest.mark.timeout(400)]

BIN = Path(sys.executable).parent
EXAMPLE = 'wall_follower.json'
PHASE = 5          # Twists heard in each phase of the robot's scan


def env() -> dict:
    """This process's environment (its ROS domain, set by the rclpy_helpers fixture) with colcon."""
    return {**os.environ, 'PATH': f'{BIN}{os.pathsep}{os.environ.get("PATH", "/usr/bin")}'}


class Rover(OwnContextNode):
    """A rover driver in a context of its own: a 360-ray /scan with a wall on the right (0.6 m),
    and, once it has heard PHASE Twists, a wall ahead (0.5 m) too; records each Twist heard."""

    def __init__(self):
        from geometry_msgs.msg import Twist
        from sensor_msgs.msg import LaserScan
        super().__init__('rover')
        self.heard: list[tuple[float, float]] = []
        self.when: list[float] = []                 # time.monotonic() of each Twist heard
        self.start_at = 0

        def hear(m):
            self.when.append(time.monotonic())
            self.heard.append((round(m.linear.x, 6), round(m.angular.z, 6)))
        self.node.create_subscription(Twist, '/cmd_vel', hear, 100)
        scan_pub = self.node.create_publisher(LaserScan, '/scan', 10)

        def scan():
            msg = LaserScan(angle_min=-math.pi, angle_max=math.pi, angle_increment=2 * math.pi / 360,
                            range_min=0.1, range_max=10.0)
            ranges = [5.0] * 360
            for i in range(75, 106):                # -105..-75 degrees: the wall on the right
                ranges[i] = 0.6
            if len(self.heard) - self.start_at >= PHASE:
                for i in range(165, 196):           # -15..15 degrees: a wall ahead
                    ranges[i] = 0.5
            msg.ranges = ranges
            scan_pub.publish(msg)

        self.node.create_timer(0.02, scan)
        self.start()

    def begin(self):
        self.start_at = len(self.heard)

    def sequence(self) -> list[tuple[float, float]]:
        """The Twists heard since begin(), repeats collapsed."""
        out = []
        for tw in self.heard[self.start_at:]:
            if not out or out[-1] != tw:
                out.append(tw)
        return out


@pytest.fixture(scope='module')
def rover(rclpy_helpers):
    r = Rover()
    yield r
    r.stop()


@pytest.fixture(scope='module')
def ide_gateway(start_gateway):
    """A gateway that serves the IDE the packages come from."""
    return start_gateway('--robot', 'rover')


@pytest.fixture(scope='module')
def graph_gateway(start_gateway):
    """A gateway on the graph (rclpy backend): the roslibpy side of each comparison."""
    return start_gateway('--backend', 'rclpy')


def from_ide(chromium, gw, program: dict | str):
    """A program's ROS 2 package (the .zip the IDE's download gives: its name and bytes), its
    roslibpy script and the node the code panel shows. program: an example's file or a program."""
    ctx = chromium.new_context(accept_downloads=True)
    ide = IdePage(ctx.new_page(), gw).open()
    if isinstance(program, str):
        ide.load_example(program)
    else:
        ide.js('(p) => rosgateIde.loadProgram(p)', program)
    script = ide.python()
    node = ide.js('async () => rosgateIde.rosNode()')
    # the code panel shows the same node once the gateway's types are read
    wait_for(lambda: ide.js("document.querySelector('#code-node').textContent") == node, what='the node in the panel')
    node_panel = node
    with ide.page.expect_download() as download:
        ide.page.click('#download-ros2')
    data = Path(download.value.path()).read_bytes()
    name = download.value.suggested_filename
    assert not ide.errors, ide.errors
    ctx.close()
    return name, data, script, node_panel


def build(data: bytes, folder: Path) -> zipfile.ZipFile:
    """colcon build of the package in the zip, in the workspace folder."""
    archive = zipfile.ZipFile(io.BytesIO(data))
    (folder / 'src').mkdir()
    archive.extractall(folder / 'src')
    started = time.monotonic()
    built = subprocess.run([str(BIN / 'colcon'), 'build'], cwd=folder, env=env(), capture_output=True, text=True, timeout=300)
    assert built.returncode == 0, built.stdout[-3000:] + built.stderr[-3000:]
    print(f'colcon build: {time.monotonic() - started:.1f} s')
    return archive


def start_node(folder: Path, pkg: str, node: str) -> subprocess.Popen:
    """The node as `ros2 run` starts it: the installed entry point with the install's Python path
    (the PyPI wheels have no ros2 command and no /opt/ros setup to source)."""
    entry = folder / 'install' / pkg / 'lib' / pkg / node
    site = next((folder / 'install' / pkg / 'lib').glob('python3*/site-packages'))
    return subprocess.Popen([sys.executable, str(entry)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**env(), 'PYTHONPATH': f'{site}{os.pathsep}{os.environ.get("PYTHONPATH", "")}'})


def drive(rover, proc: subprocess.Popen) -> tuple[list, str]:
    """Lets the program drive through both phases, then Ctrl-C; the Twists the rover heard."""
    enough = True
    try:
        wait_for(lambda: len(rover.heard) - rover.start_at >= 2 * PHASE + 3, 60)
    except AssertionError:
        enough = False
    interrupted = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=30)
    assert enough, f'the rover heard {rover.sequence()}; the program said: {out[-3000:]}'
    wait_for(lambda: rover.heard[-1] == (0.0, 0.0), 10)
    print(f'Ctrl-C to the zero Twist at the rover: {1000 * (rover.when[-1] - interrupted):.0f} ms')
    return rover.sequence(), out


def test_the_package_builds_and_drives_as_the_script_does(rover, chromium, ide_gateway, graph_gateway, tmp_path):
    name, data, script, node_panel = from_ide(chromium, ide_gateway, EXAMPLE)
    assert name == 'rover wall-follower.zip'
    pkg = 'rover_wall_follower'
    node = pkg
    archive = build(data, tmp_path)
    files = set(archive.namelist())
    assert files == {f'{pkg}/{f}' for f in ('package.xml', 'setup.py', 'setup.cfg', f'resource/{pkg}', f'{pkg}/__init__.py',
                                             f'{pkg}/{node}.py', 'README.md')}, files
    xml = archive.read(f'{pkg}/package.xml').decode()
    for dep in ('rclpy', 'geometry_msgs', 'sensor_msgs'):
        assert f'<exec_depend>{dep}</exec_depend>' in xml
    readme = archive.read(f'{pkg}/README.md').decode()
    assert 'colcon build' in readme and f'ros2 run {pkg} {node}' in readme
    code = archive.read(f'{pkg}/{pkg}/{node}.py').decode()
    assert code == node_panel                    # the code panel shows the node the package carries
    assert "self.cmd_vel_pub = self.create_publisher(Twist, 'cmd_vel', 10)" in code
    assert "self.create_subscription(LaserScan, 'scan', self.on_scan, 10)" in code
    assert 'import *' not in code and 'rosgate' not in code.split('"""', 2)[2]

    # the roslibpy script through a gateway on the graph
    (tmp_path / 'script.py').write_text(script)
    rover.begin()
    proc = subprocess.Popen([sys.executable, str(tmp_path / 'script.py'), '--url', graph_gateway.ws_url],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    by_script, out = drive(rover, proc)
    print('script:', by_script, out[-500:])

    rover.begin()
    proc = start_node(tmp_path, pkg, node)
    by_node, out = drive(rover, proc)
    print('node:', by_node, out[-500:])
    assert proc.returncode == 0, out
    expected = [(0.35, 0.0), (0.0, round(math.radians(60), 6)), (0.0, 0.0)]
    assert by_script == expected
    assert by_node == expected


def test_the_nodes_servers_answer_roslibpy_through_the_gateway(rclpy_helpers, chromium, ide_gateway, graph_gateway,
                                                              tmp_path):
    from .rclpy_nodes import find
    add_type, fib_type = find('add')[0], find('fibonacci')[0]
    name, data, _, code = from_ide(chromium, ide_gateway, program(add_type, fib_type))
    assert name == 'served.zip'
    srv, action = add_type.split('/')[-1], fib_type.split('/')[-1]
    assert f"self.create_service({srv}, '/add_served', self.on_call, callback_group=self.group)" in code
    assert f"ActionServer(self, {action}, '/count_served', self.on_goal, callback_group=self.group)" in code
    assert "self.served_ticks_pub = self.create_publisher(String, '/served_ticks', 10)" in code
    assert 'self.create_timer(0.1, self.every_tick, callback_group=self.group)' in code
    build(data, tmp_path)
    proc = start_node(tmp_path, 'served', 'served')
    try:
        with client(graph_gateway) as ros:
            check_served(ros, add_type, fib_type)
    finally:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=30)
    print(out[-2000:])
    assert proc.returncode == 0 and 'Traceback' not in out, out


@pytest.fixture(scope='module')
def trusted_gateway(start_gateway, tmp_path_factory):
    """A gateway on the graph that runs programs as nodes of it (--trusted-runs), whose ROS variables
    its runs take: over UDP, discovering the subnet's peers (a run is another user, who may not
    open the robot's shared memory, as test_run_graph's trusted run)."""
    folder = tmp_path_factory.mktemp('node-runs')
    return start_gateway('--backend', 'rclpy', '--allow-runs', '--trusted-runs', '--runs-dir', str(folder / 'runs'),
                         env={'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4', 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'})


def test_with_trusted_runs_the_ides_run_on_robot_runs_the_node(rover, chromium, trusted_gateway):
    """The IDE on a gateway whose runs are nodes of the graph: "Run on robot" sends the block program
    as its ROS 2 node (kind ros2_node); the gateway starts it as a node, the rover hears the script's
    Twists, and Stop ends it with zero velocity. A source that is not an rclpy program is refused,
    saying why."""
    status, listing = api(trusted_gateway, 'GET', '/api/runs')
    assert status == 200 and listing['nodes'] is True
    ctx = chromium.new_context()
    ide = IdePage(ctx.new_page(), trusted_gateway).open()
    try:
        ide.load_example(EXAMPLE)
        ide.page.wait_for_selector('#run-robot', state='visible')
        rover.begin()
        ide.page.click('#run-robot')
        try:
            wait_for(lambda: len(rover.heard) - rover.start_at >= 2 * PHASE + 3, 60)
        except AssertionError:
            raise AssertionError(f'the rover heard {rover.sequence()}; runs: {api(trusted_gateway, "GET", "/api/runs")}; '
                                 f'console: {ide.console_text()[-2000:]}') from None
        finally:
            ide.page.click('#stop')
        runs = api(trusted_gateway, 'GET', '/api/runs')[1]['runs']
        final = ended(trusted_gateway, runs[-1]['id'])
    finally:
        ctx.close()
    wait_for(lambda: rover.heard[-1] == (0.0, 0.0), 10)
    assert rover.sequence() == [(0.35, 0.0), (0.0, round(math.radians(60), 6)), (0.0, 0.0)], final['output'][-2000:]
    # the node's own log lines (rclpy's format): the run was the node, not the roslibpy script
    assert '[rover_wall_follower]: following the wall on the right' in final['output'], final['output'][-2000:]
    status, body = api(trusted_gateway, 'POST', '/api/runs', {'source': 'print(1)\n', 'kind': 'ros2_node'})
    assert status == 400 and 'rclpy' in body['error'], body
