"""The rover, black-box through the websocket, in a small world with a box 1.5 m ahead."""

from __future__ import annotations

import base64
import io
import math
import time

import pytest
import roslibpy
from PIL import Image

from tests.support.fixtures import client_of
from tests.support.ros import Inbox, call, stream, twist
from tests.support.wait import wait_for

RADIUS = 0.18
TOPICS = {
    '/cmd_vel': 'geometry_msgs/msg/Twist',
    '/odom': 'nav_msgs/msg/Odometry',
    '/tf': 'tf2_msgs/msg/TFMessage',
    '/tf_static': 'tf2_msgs/msg/TFMessage',
    '/scan': 'sensor_msgs/msg/LaserScan',
    '/imu': 'sensor_msgs/msg/Imu',
    '/battery_state': 'sensor_msgs/msg/BatteryState',
    '/motor/left/temperature': 'sensor_msgs/msg/Temperature',
    '/motor/right/temperature': 'sensor_msgs/msg/Temperature',
    '/bumper': 'std_msgs/msg/Bool',
    '/camera/image_raw/compressed': 'sensor_msgs/msg/CompressedImage',
    '/world/markers': 'visualization_msgs/msg/MarkerArray',
    '/robot_description': 'std_msgs/msg/String',
    '/joint_states': 'sensor_msgs/msg/JointState',
}


ros = client_of('rover_gw', 'module')


@pytest.fixture
def fresh(ros):
    call(ros, '/reset_world', 'std_srvs/srv/Empty')
    return ros


def yaw_of(q: dict) -> float:
    return 2 * math.atan2(q['z'], q['w'])


def test_rover_interfaces(fresh):
    ros = fresh
    for name, type in TOPICS.items():
        assert ros.get_topic_type(name) == type, name
    assert ros.get_service_type('/reset_world') == 'std_srvs/srv/Empty'
    assert roslibpy.Param(ros, '/rover:max_linear_velocity').get(timeout=5) == 0.8
    scan = Inbox(ros, '/scan', 'sensor_msgs/msg/LaserScan').wait()
    assert len(scan['ranges']) == 360 and scan['angle_min'] == 0.0
    assert scan['angle_increment'] == pytest.approx(2 * math.pi / 360)
    assert scan['header']['frame_id'] == 'base_scan'
    assert scan['ranges'][0] == pytest.approx(1.5, abs=1e-3)          # the box straight ahead
    assert scan['ranges'][180] == pytest.approx(1.0, abs=1e-3)        # the wall behind
    assert scan['ranges'][90] == pytest.approx(2.0, abs=1e-3)         # the walls to the sides
    static = Inbox(ros, '/tf_static', 'tf2_msgs/msg/TFMessage').wait()
    assert {'odom', 'base_scan', 'camera_link', 'imu_link'} <= {t['child_frame_id'] for t in static['transforms']}


def test_driving_at_a_wall_stops_the_rover(fresh):
    ros = fresh
    scans = Inbox(ros, '/scan', 'sensor_msgs/msg/LaserScan')
    bumper = Inbox(ros, '/bumper', 'std_msgs/msg/Bool')
    odom = Inbox(ros, '/odom', 'nav_msgs/msg/Odometry')
    log = Inbox(ros, '/rosout', 'rcl_interfaces/msg/Log')
    pub = roslibpy.Topic(ros, '/cmd_vel', 'geometry_msgs/msg/Twist')
    try:
        assert bumper.wait()['data'] is False
        scans.wait()
        deadline = time.monotonic() + 5
        while not (bumper.last or {}).get('data') and time.monotonic() < deadline:
            stream(pub, twist(0.8), 0.1)
        assert bumper.last['data'] is True
        contact = odom.wait(after=time.monotonic())['pose']['pose']['position']['x']
        assert contact == pytest.approx(1.5 - RADIUS, abs=0.01)
        stream(pub, twist(0.8), 0.6)                       # pushing on does not move it
        after = odom.wait(after=time.monotonic())
        assert after['pose']['pose']['position']['x'] == pytest.approx(contact, abs=0.005)
        assert after['twist']['twist']['linear']['x'] == 0.0
        assert bumper.last['data'] is True
        ahead = [min(s['ranges'][:5] + s['ranges'][-5:]) for s in scans.messages]
        assert ahead[0] == pytest.approx(1.5, abs=0.01) and ahead[-1] == pytest.approx(RADIUS, abs=0.01)
        assert all(b <= a + 1e-6 for a, b in zip(ahead, ahead[1:]))   # shrinks as it approaches
        assert min(min(s['ranges']) for s in scans.messages[-2:]) == pytest.approx(RADIUS, abs=0.01)
        assert log.wait(lambda m: 'Bumped into a wall' in m['msg'])['level'] == 30
        stream(pub, twist(-0.3), 0.5)                      # backing away is allowed
        bumper.wait(lambda m: m['data'] is False)
    finally:
        for inbox in (scans, bumper, odom, log):
            inbox.close()


def test_odometry_integrates_the_motion(fresh):
    ros = fresh
    odom = Inbox(ros, '/odom', 'nav_msgs/msg/Odometry')
    tf = Inbox(ros, '/tf', 'tf2_msgs/msg/TFMessage')
    imu = Inbox(ros, '/imu', 'sensor_msgs/msg/Imu')
    pub = roslibpy.Topic(ros, '/cmd_vel', 'geometry_msgs/msg/Twist')
    try:
        start = odom.wait()
        assert start['pose']['pose']['position'] == {'x': 0.0, 'y': 0.0, 'z': 0.0}
        assert start['header']['frame_id'] == 'odom' and start['child_frame_id'] == 'base_link'
        last = stream(pub, twist(0.4, 0.6), 1.5)
        end = odom.wait(lambda m: m['twist']['twist']['linear']['x'] == 0.0 and
                        m['twist']['twist']['angular']['z'] == 0.0, timeout=3, after=last)
        msgs = odom.messages[:odom.messages.index(end) + 1]
        x = y = yaw = 0.0
        for a, b in zip(msgs, msgs[1:]):
            dt = (b['header']['stamp']['sec'] - a['header']['stamp']['sec']) + \
                 (b['header']['stamp']['nanosec'] - a['header']['stamp']['nanosec']) * 1e-9
            v, w = b['twist']['twist']['linear']['x'], b['twist']['twist']['angular']['z']
            x += v * math.cos(yaw + w * dt / 2) * dt
            y += v * math.sin(yaw + w * dt / 2) * dt
            yaw += w * dt
        pose = end['pose']['pose']
        assert pose['position']['x'] > 0.3 and pose['position']['y'] > 0.05
        assert (pose['position']['x'], pose['position']['y']) == pytest.approx((x, y), abs=0.06)
        assert yaw_of(pose['orientation']) == pytest.approx(yaw, abs=0.08)
        assert yaw == pytest.approx(0.6 * (1.5 + 0.5), abs=0.12)    # the last command holds for 0.5 s
        moved = tf.wait(lambda m: m['transforms'][0]['transform']['translation']['x'] == pose['position']['x'])
        assert moved['transforms'][0]['header']['frame_id'] == 'odom'
        assert yaw_of(imu.last['orientation']) == pytest.approx(yaw_of(pose['orientation']), abs=1e-6)
        assert imu.last['linear_acceleration']['z'] == pytest.approx(9.80665)
    finally:
        for inbox in (odom, tf, imu):
            inbox.close()


def test_battery_drains_and_motors_warm_up(fresh):
    ros = fresh
    pub = roslibpy.Topic(ros, '/cmd_vel', 'geometry_msgs/msg/Twist')
    with (Inbox(ros, '/battery_state', 'sensor_msgs/msg/BatteryState') as battery,
          Inbox(ros, '/motor/left/temperature', 'sensor_msgs/msg/Temperature') as left):
        full = battery.wait()
        assert full['percentage'] == pytest.approx(1.0, abs=1e-4) and full['present'] is True
        cold = left.wait()['temperature']
        assert cold == pytest.approx(25.0, abs=0.1)
        t = time.monotonic()
        idle = battery.wait(after=t)['percentage']
        stream(pub, twist(0.0, 2.5), 1.5)     # spinning in place: the wheels work, nothing is hit
        t = time.monotonic()
        driven = battery.wait(after=t)
        warm = left.wait(after=t)['temperature']
        assert 0 <= driven['percentage'] < idle < 1.0
        assert (idle - driven['percentage']) > 2 * (1.0 - idle)   # motion drains faster than idling
        assert driven['voltage'] < full['voltage']
        assert warm > cold + 0.1      # a first-order rise towards a load-dependent temperature


def test_camera_publishes_a_decodable_jpeg(fresh):
    ros = fresh
    with Inbox(ros, '/camera/image_raw/compressed', 'sensor_msgs/msg/CompressedImage') as camera:
        first = camera.wait()
        start = time.monotonic()
        wait_for(lambda: len(camera.since(start)) >= 5, timeout=3)
        rate = (len(camera.since(start)) - 1) / (time.monotonic() - start)
        assert 3 < rate < 8
    assert 'jpeg' in first['format']
    image = Image.open(io.BytesIO(base64.b64decode(first['data'])))
    assert image.format == 'JPEG' and image.size == (160, 120)
    r, g, b = image.convert('RGB').getpixel((80, 62))     # the red box straight ahead
    assert r > 120 and r > 2 * g and r > 2 * b


def test_reset_world_restores_everything(fresh):
    ros = fresh
    pub = roslibpy.Topic(ros, '/cmd_vel', 'geometry_msgs/msg/Twist')
    with (Inbox(ros, '/odom', 'nav_msgs/msg/Odometry') as odom,
          Inbox(ros, '/battery_state', 'sensor_msgs/msg/BatteryState') as battery):
        stream(pub, twist(0.5, 1.0), 0.6)
        odom.wait(lambda m: m['pose']['pose']['position']['x'] > 0.1)
        battery.wait(lambda m: m['percentage'] < 1.0)
        t = time.monotonic()
        call(ros, '/reset_world', 'std_srvs/srv/Empty')
        origin = {'x': 0.0, 'y': 0.0, 'z': 0.0}
        odom.wait(lambda m: m['pose']['pose']['position'] == origin, after=t)
        assert battery.wait(lambda m: m['percentage'] == 1.0, after=t)['voltage'] > 12.5
        t = time.monotonic()
        assert odom.wait(after=t)['pose']['pose']['position'] == origin   # and it stays there


def test_rover_world_markers(fresh):
    ros = fresh
    with Inbox(ros, '/world/markers', 'visualization_msgs/msg/MarkerArray') as markers:
        snapshot = markers.wait()
        by_ns = {}
        for m in snapshot['markers']:
            by_ns.setdefault(m['ns'], []).append(m)
        assert [m['type'] for m in by_ns['bounds']] == [4]
        assert [(p['x'], p['y']) for p in by_ns['bounds'][0]['points']][:3] == [(0, 0), (6, 0), (6, 4)]
        (wall,) = by_ns['walls']
        assert wall['type'] == 1 and wall['pose']['position']['x'] == 2.75 and wall['scale']['y'] == 1.2
        (robot,) = by_ns['robots']
        assert robot['text'] == 'rover' and robot['pose']['position']['x'] == pytest.approx(1.0)
        scan = markers.wait(lambda m: any(x['ns'] == 'scan' for x in m['markers']))
        points = next(x for x in scan['markers'] if x['ns'] == 'scan')['points']
        assert len(points) == 360
        assert all(-1e-6 <= p['x'] <= 6 + 1e-6 and -1e-6 <= p['y'] <= 4 + 1e-6 for p in points)


def test_a_still_rovers_scan_marker_is_sent_once_and_again_when_it_moves(fresh):
    ros = fresh
    markers = Inbox(ros, '/world/markers', 'visualization_msgs/msg/MarkerArray')
    pub = roslibpy.Topic(ros, '/cmd_vel', 'geometry_msgs/msg/Twist')
    try:
        markers.wait()
        start = time.monotonic()
        wait_for(lambda: time.monotonic() - start > 1.5, timeout=5)   # 7 scans at 5 Hz
        scans = [m for m in markers.since(start) if any(x['ns'] == 'scan' for x in m['markers'])]
        assert len(scans) <= 1
        moved = time.monotonic()
        stream(pub, twist(0.0, 1.0), 0.5)
        wait_for(lambda: any(x['ns'] == 'scan' for m in markers.since(moved) for x in m['markers']), timeout=5)
    finally:
        markers.close()
        pub.unadvertise()


def test_velocity_limits_are_parameters(fresh):
    ros = fresh
    limit = roslibpy.Param(ros, '/rover:max_linear_velocity')
    odom = Inbox(ros, '/odom', 'nav_msgs/msg/Odometry')
    pub = roslibpy.Topic(ros, '/cmd_vel', 'geometry_msgs/msg/Twist')
    try:
        limit.set(0.2, timeout=5)
        bad = call(ros, '/rosapi/set_param', 'rosapi_msgs/srv/SetParam',
                   {'name': '/rover:max_linear_velocity', 'value': '-1'})
        assert bad['successful'] is False and limit.get(timeout=5) == 0.2
        start = time.monotonic()
        stream(pub, twist(-0.8), 0.7)                 # backwards: away from the box
        speeds = [m['twist']['twist']['linear']['x'] for m in odom.since(start)]
        assert min(speeds) == pytest.approx(-0.2) and max(speeds) <= 0.0
        ramp = [s for s in speeds if -0.2 < s < 0]    # 1.5 m/s² up to the limit: a few 40 ms samples
        assert 1 <= len(ramp) <= 5
    finally:
        limit.set(0.8, timeout=5)
        odom.close()


def test_a_world_that_does_not_exist_is_refused():
    import subprocess
    import sys

    from tests.support.process import ROOT
    done = subprocess.run([sys.executable, '-m', 'gateway', '--port', '0', '--address', '127.0.0.1',
                           '--robot', 'rover', '--world', 'no_such_world'],
                          cwd=ROOT, capture_output=True, text=True, timeout=30)
    assert done.returncode != 0 and done.stdout == ''
    assert "no world 'no_such_world'" in done.stderr and 'arena, maze' in done.stderr


def test_camera_of_a_still_robot_is_encoded_once():
    """The same pose gives the same bytes without rendering again; another pose renders anew."""
    import math

    from gateway.backends.sim.robots.camera import Camera
    from gateway.backends.sim.robots.world import World
    cam = Camera(World.load('arena'))
    renders = []
    original = cam.render
    cam.render = lambda *a: renders.append(a) or original(*a)
    first = cam.jpeg(1.0, 1.0, 0.5)
    assert cam.jpeg(1.0, 1.0, 0.5) is first and len(renders) == 1
    turned = cam.jpeg(1.0, 1.0, 0.5 + math.pi / 2)
    assert turned != first and len(renders) == 2


def test_the_rover_describes_itself_as_a_real_robot(fresh):
    """robot_description retained for late subscribers (a URDF whose links are the rover's TF
    frames); joint_states turn the wheels by the distance each rolled."""
    import xml.etree.ElementTree as ET
    ros = fresh
    description = Inbox(ros, '/robot_description', 'std_msgs/msg/String')
    joints = Inbox(ros, '/joint_states', 'sensor_msgs/msg/JointState')
    pub = roslibpy.Topic(ros, '/cmd_vel', 'geometry_msgs/msg/Twist')
    try:
        robot = ET.fromstring(description.wait()['data'])   # published at start, long before this subscribe
        links = {link.get('name') for link in robot.iter('link')}
        assert {'base_link', 'base_scan', 'left_wheel_link', 'right_wheel_link'} <= links
        kinds = {j.get('name'): j.get('type') for j in robot.iter('joint')}
        assert kinds['left_wheel_joint'] == kinds['right_wheel_joint'] == 'continuous'
        first = joints.wait()
        assert first['name'] == ['left_wheel_joint', 'right_wheel_joint']
        assert first['position'] == [0.0, 0.0]
        last = stream(pub, twist(0.0, 1.0), 1.0)       # turning left on the spot: the wheels turn apart
        still = joints.wait(lambda m: m['velocity'] == [0.0, 0.0], timeout=3, after=last)
        left, right = still['position']
        assert left < -1.0 and right > 1.0 and left == pytest.approx(-right, rel=0.01), (left, right)
    finally:
        for inbox in (description, joints):
            inbox.close()
