"""A robot-side run on a real ROS 2 graph (rclpy, Fast DDS), against a gateway started as a class
on a robot would (``--backend rclpy --auth --exclusive-control --allow-runs``), with a robot node
listening on /turtle1/cmd_vel: the run reaches the graph only through the gateway (where its
starter may drive), never by DDS of its own, and no port of the machine but the gateway's.

Run inside a loopback-only network namespace, as ``make test-rclpy`` does.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.auth import TOKENS, tokens_toml
from tests.support.contract import rclpy_missing
from tests.support.http import api
from tests.support.process import descendants, uids
from tests.support.wait import wait_for

from .rclpy_nodes import OwnContextNode

ROOT = Path(__file__).resolve().parents[2]
RUNTIME = (ROOT / 'ide' / 'runtime' / 'rosgate_runtime.py').read_text()
ENDED = ('finished', 'failed', 'stopped', 'timed_out')

pytestmark = pytest.mark.skipif(rclpy_missing() is not None, reason=f'rclpy does not import: {rclpy_missing()}')

# What an attacker's program does: its own DDS participant on the robot's domain, 50 Twists at 9 m/s.
# UDPv4: Fast DDS's UDP transport alone, discovery by the subnet's rules (the LOCALHOST range would
# bring back shared memory, which a box's private /dev/shm happens to break); default: as the robot.
SPEAKS_DDS = '''import os, sys, time
os.environ["ROS_DOMAIN_ID"] = {domain!r}
{transports}import rclpy
from geometry_msgs.msg import Twist
rclpy.init()
node = rclpy.create_node("intruder")
pub = node.create_publisher(Twist, "/turtle1/cmd_vel", 10)
msg = Twist()
msg.linear.x = 9.0
deadline = time.monotonic() + 8
while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
    time.sleep(0.05)
print("subscribers", pub.get_subscription_count(), flush=True)
deadline = time.monotonic() + 3
sent = 0
while time.monotonic() < deadline:
    pub.publish(msg)
    sent += 1
    time.sleep(0.05)
print("published", sent, flush=True)
node.destroy_node()
rclpy.shutdown()
'''

TRANSPORTS = {
    'UDPv4': 'os.environ["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"\nos.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"\n',
    'default': 'os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"\n',
}


class Robot(OwnContextNode):
    """A robot driver in a context of its own: counts the Twists it hears on /turtle1/cmd_vel."""

    def __init__(self):
        from geometry_msgs.msg import Twist
        super().__init__('turtlesim')
        self.heard: list[float] = []
        self.node.create_subscription(Twist, '/turtle1/cmd_vel', lambda m: self.heard.append(m.linear.x), 10)
        self.start()


@pytest.fixture(scope='module')
def robot(rclpy_helpers):
    r = Robot()
    yield r
    r.stop()


@pytest.fixture(scope='module')
def robot_gw(start_gateway, tmp_path_factory, robot):
    folder = tmp_path_factory.mktemp('robot-runs')
    (folder / 'tokens.toml').write_text(tokens_toml())
    gw = start_gateway('--backend', 'rclpy', '--auth', str(folder / 'tokens.toml'), '--exclusive-control',
                       '--allow-runs', '--runs-dir', str(folder / 'runs'),
                       env={'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'})
    return gw


def state(gw, path: str, who: str, method: str = 'GET', body=None):
    return api(gw, method, path, body, TOKENS[who])


def run(gw, source: str, who: str = 'operator', **kw) -> dict:
    """Start a run as ``who`` and wait for its end; its final state."""
    status, body = state(gw, '/api/runs', who, 'POST', {'source': source, 'name': 'graph test', **kw})
    assert status == 201, body
    return ended(gw, body['id'], who)


def ended(gw, run_id: str, who: str) -> dict:
    return wait_for(lambda: (lambda s: s if s['state'] in ENDED else None)(state(gw, f'/api/runs/{run_id}', who)[1]),
                    120, 0.05)


def domain() -> str:
    return os.environ['ROS_DOMAIN_ID']


def test_outside_a_box_the_same_program_reaches_the_robot(robot, tmp_path):
    """The check below can fail: the attacker's program, run as an ordinary process, is heard."""
    before = len(robot.heard)
    done = subprocess.run([sys.executable, '-c', SPEAKS_DDS.format(
        domain=domain(), transports=TRANSPORTS['UDPv4'])],
        capture_output=True, text=True, timeout=120, env={'PATH': os.environ.get('PATH', '/usr/bin'), 'HOME': str(tmp_path)})
    assert 'published' in done.stdout, done.stderr[-2000:]
    wait_for(lambda: len(robot.heard) > before, 10)


@pytest.mark.parametrize('transports', ['UDPv4', 'default'])
def test_the_robot_hears_nothing_straight_from_a_run(robot_gw, robot, transports):
    before = len(robot.heard)
    final = run(robot_gw, SPEAKS_DDS.format(domain=domain(), transports=TRANSPORTS[transports]))
    print(final['output'])
    assert 'published' in final['output'], final       # its own participant was up and publishing
    assert len(robot.heard) == before, f'the robot heard {len(robot.heard) - before} Twists from the run'


def test_a_run_gets_no_ros_variable_of_the_gateway(robot_gw):
    final = run(robot_gw, 'import os\nprint(sorted(k for k in os.environ if k.startswith(("ROS_", "RMW_", "FASTDDS_", '
                          '"FASTRTPS_", "CYCLONEDDS_"))), flush=True)\n')
    assert final['state'] == 'finished' and '[]' in final['output'], final


PROBE_PORTS = '''import socket
for family, kind, name in ((socket.AF_INET, socket.SOCK_STREAM, "tcp"), (socket.AF_INET, socket.SOCK_DGRAM, "udp")):
    for host in ("127.0.0.1", {address!r}):
        s = socket.socket(family, kind)
        s.settimeout(3)
        try:
            port = {tcp} if name == "tcp" else {udp}
            if name == "tcp":
                s.connect((host, port))
                s.sendall(b"from the run")
            else:
                for _ in range(20):
                    s.sendto(b"from the run", (host, port))
            print(name, host, "sent", flush=True)
        except OSError as e:
            print(name, host, "refused:", e, flush=True)
        finally:
            s.close()
'''


def own_address() -> str:
    """An address of this machine besides loopback, or loopback again where there is none."""
    try:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.connect(('192.0.2.1', 9))
        return s.getsockname()[0]
    except OSError:
        return '127.0.0.1'


def test_a_checkers_tcp_and_udp_listeners_hear_nothing_from_a_run(robot_gw):
    tcp = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    tcp.bind(('0.0.0.0', 0))
    tcp.listen()
    tcp.settimeout(0.2)
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(('0.0.0.0', 0))
    udp.settimeout(0.2)
    heard = []
    try:
        final = run(robot_gw, PROBE_PORTS.format(tcp=tcp.getsockname()[1], udp=udp.getsockname()[1],
                                                 address=own_address()))
        print(final['output'])
        assert final['state'] == 'finished' and final['output'].count('refused') == 4, final
        for sock in (tcp, udp):
            try:
                heard.append(sock.accept() if sock is tcp else sock.recvfrom(100))
            except (TimeoutError, socket.timeout):
                pass
        assert heard == []
        # the listeners work: this process is heard at once
        with socket.create_connection(('127.0.0.1', tcp.getsockname()[1]), timeout=5):
            assert tcp.accept()
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM).sendto(b'x', ('127.0.0.1', udp.getsockname()[1]))
        assert udp.recvfrom(10)[0] == b'x'
    finally:
        tcp.close()
        udp.close()


DRIVES = RUNTIME + '''

def main():
    rt.log("driving")
    rt.drive("/turtle1/cmd_vel", "geometry_msgs/msg/Twist", {"linear": {"x": 0.5}}, 1.5)
    rt.log("drove")

if __name__ == "__main__":
    run(main)
'''


def drives_through_the_gateway(gw, robot, processes: int = 1) -> None:
    """A run of DRIVES drives the robot through the gateway, and none of its processes (at least
    ``processes`` of them, seen from the gateway's side) is uid 0."""
    before = len(robot.heard)
    status, body = state(gw, '/api/runs', 'operator', 'POST', {'source': DRIVES, 'name': 'drives'})
    assert status == 201, body
    run_id = body['id']
    try:
        wait_for(lambda: 'driving' in state(gw, f'/api/runs/{run_id}', 'operator')[1]['output'], 60)
        procs = {p: uids(p) for p in descendants(gw.pid)}
        print(procs)
        assert len(procs) >= processes, procs
        assert all(u and 0 not in u for u in procs.values()), procs
        final = ended(gw, run_id, 'operator')
    finally:      # a failure above leaves no run holding the root namespace for the next test
        state(gw, f'/api/runs/{run_id}', 'admin', 'DELETE')
        ended(gw, run_id, 'admin')
    assert final['state'] == 'finished' and 'drove' in final['output'], final
    wait_for(lambda: 0.5 in robot.heard[before:], 10)


def test_a_run_drives_through_the_gateway_and_is_no_root_outside(robot_gw, robot):
    drives_through_the_gateway(robot_gw, robot, processes=3)   # bwrap, its init, the program (and the relay)


def test_another_operators_get_of_a_run_is_403(robot_gw):
    final = run(robot_gw, 'print("mine")')
    assert state(robot_gw, f'/api/runs/{final["id"]}', 'operator2')[0] == 403
    assert state(robot_gw, f'/api/runs/{final["id"]}', 'admin')[0] == 200
    assert final['id'] not in [r['id'] for r in state(robot_gw, '/api/runs', 'operator2')[1]['runs']]


@pytest.fixture(scope='module')
def trusted_gw(start_gateway, tmp_path_factory, robot):
    folder = tmp_path_factory.mktemp('trusted-runs')
    (folder / 'tokens.toml').write_text(tokens_toml())
    return start_gateway('--backend', 'rclpy', '--auth', str(folder / 'tokens.toml'), '--exclusive-control',
                         '--allow-runs', '--trusted-runs', '--runs-dir', str(folder / 'runs'),
                         env={'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'})


def test_a_trusted_run_is_a_node_of_the_graph(trusted_gw, robot):
    """--trusted-runs (never the default, and said at start-up to be outside the rules): a program
    that is a ROS 2 node is heard by the robot (over UDP: a run is another user than the robot's
    nodes, whose shared memory it may not open); it is still not root outside, and still obeys
    the gateway where it speaks rosbridge."""
    assert 'outside every rule of this gateway' in trusted_gw.log_text()
    before = len(robot.heard)
    final = run(trusted_gw, SPEAKS_DDS.format(domain=domain(), transports=TRANSPORTS['UDPv4']))
    assert 'published' in final['output'], final
    wait_for(lambda: len(robot.heard) > before, 10)
    assert 9.0 in robot.heard[before:]
    env = run(trusted_gw, 'import os\nprint(os.environ.get("ROS_DOMAIN_ID"), os.environ.get("FASTDDS_BUILTIN_TRANSPORTS"),'
                          ' "ROSGATE_TOKEN" in os.environ, flush=True)\n')
    assert f'{domain()} UDPv4 False' in env['output'], env
    drives_through_the_gateway(trusted_gw, robot)
