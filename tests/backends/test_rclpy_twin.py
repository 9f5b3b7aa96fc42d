"""What the twin reads of a real robot, on the rclpy backend: a plain rclpy robot (its own context)
publishes its description on ``/bot/robot_description`` (transient local, once, before anyone
listens) and holds it as robot_state_publisher's parameter; publishes its map (transient local)
and joint states. A page that connects later still gets the description and the map (durability
honoured for late subscribers, also for a second client of the shared subscription), the map
made to measure; the description's meshes come from --mesh-path and AMENT_PREFIX_PATH at
/package/, and escapes are refused."""

from __future__ import annotations

import http.client
import json
import os

import pytest
import roslibpy

from tests.support.ros import client
from tests.support.wait import wait_for
from tests.support.testbot import URDF, occupancy_grid, write_package

from tests.support.contract import rclpy_missing

pytestmark = [
    pytest.mark.asyncio(loop_scope='session'),
    pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here'),
]


def get(port: int, path: str) -> tuple[int, bytes]:
    conn = http.client.HTTPConnection('127.0.0.1', port, timeout=10)
    try:
        conn.putrequest('GET', path, skip_accept_encoding=True)
        conn.endheaders()
        r = conn.getresponse()
        return r.status, r.read()
    finally:
        conn.close()


@pytest.fixture
def robot(caller):
    """The robot's nodes in the caller's context: its description (topic and parameter) and map."""
    from nav_msgs.msg import OccupancyGrid
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import String

    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    rsp = Node('robot_state_publisher', namespace='/bot', context=caller.context)
    rsp.declare_parameter('robot_description', URDF)
    rsp.create_publisher(String, 'robot_description', latched).publish(String(data=URDF))
    grid = occupancy_grid(side=1000)
    msg = OccupancyGrid()
    msg.header.frame_id = 'map'
    msg.info.width = msg.info.height = 1000
    msg.info.resolution = 0.02
    msg.info.origin.position.x = msg.info.origin.position.y = -10.0
    msg.data = grid['data']
    rsp.create_publisher(OccupancyGrid, 'map', latched).publish(msg)
    caller.executor.add_node(rsp)
    yield rsp
    caller.executor.remove_node(rsp)
    rsp.destroy_node()


@pytest.fixture(scope='module')
def gateway(rclpy_helpers, start_gateway, tmp_path_factory):
    meshes = write_package(tmp_path_factory.mktemp('mesh-path'))
    prefix = tmp_path_factory.mktemp('prefix')
    write_package(prefix / 'share')
    os.rename(prefix / 'share' / 'testbot', prefix / 'share' / 'prefixbot')
    return start_gateway('--backend', 'rclpy', '--mesh-path', str(meshes),
                         env={'AMENT_PREFIX_PATH': f'{prefix}{os.pathsep}{os.environ.get("AMENT_PREFIX_PATH", "")}'})


async def test_a_late_page_gets_the_description_the_parameter_and_the_map(gateway, robot):
    with client(gateway) as ros, client(gateway) as second:
        got, again = [], []
        # a page that comes later than the robot: the gateway has discovered its publisher (and so
        # its durability) before the page subscribes
        wait_for(lambda: '/bot/robot_description' in ros.get_topics(), 20)
        roslibpy.Topic(ros, '/bot/robot_description', 'std_msgs/msg/String').subscribe(got.append)
        wait_for(lambda: got, 20)
        assert got[0]['data'] == URDF
        roslibpy.Topic(second, '/bot/robot_description', 'std_msgs/msg/String').subscribe(again.append)
        wait_for(lambda: again, 20)                              # a second client of the shared subscription
        assert again[0]['data'] == URDF

        value = roslibpy.Service(ros, '/rosapi/get_param', 'rosapi/GetParam').call(
            roslibpy.ServiceRequest({'name': '/bot/robot_state_publisher:robot_description', 'default_value': ''}),
            timeout=20)
        assert json.loads(value['value']) == URDF

        maps = []
        ros.on('/bot/map', maps.append)
        ros.send_on_ready(roslibpy.Message({'op': 'subscribe', 'id': 'map-small', 'topic': '/bot/map',
                                            'type': 'nav_msgs/msg/OccupancyGrid', 'image': {'width': 250}}))
        wait_for(lambda: maps, 20)
        info = maps[0]['info']
        assert (info['width'], info['height']) == (250, 250) and info['resolution'] == pytest.approx(0.08)
        data = maps[0]['data']
        assert len(data) == 250 * 250 and data[0] == 100 and data[125 * 250 + 125] == 0


async def test_the_meshes_are_served_and_escapes_refused(gateway):
    status, body = get(gateway.port, '/package/testbot/meshes/wheel.dae')
    assert status == 200 and b'<COLLADA' in body
    status, body = get(gateway.port, '/package/prefixbot/meshes/body.stl')        # AMENT_PREFIX_PATH share
    assert status == 200 and body.startswith(b'solid body')
    for path in ('/package/testbot/../../etc/passwd', '/package/testbot/meshes/%2e%2e/%2e%2e/package.xml',
                 '/package/testbot/%2Fetc%2Fpasswd', '/package/testbot/meshes/body.stl%00',
                 '/package/%2e%2e/testbot/meshes/body.stl', '/package/testbot/meshes/..%5cbody.stl',
                 '/package/testbot/package.xml/..', '/package/testbot/.git/config'):
        status, body = get(gateway.port, path)
        assert status in (403, 404) and b'root:' not in body, (path, status)


@pytest.fixture
def lidar(caller):
    """A real rclpy node publishing a 16x2000 organised PointCloud2 (x, y, z, rgb; NaN where a beam had
    no return) at 10 Hz."""
    import numpy as np
    from rclpy.node import Node
    from sensor_msgs.msg import PointCloud2, PointField

    node = Node('lidar', namespace='/bot', context=caller.context)
    pub = node.create_publisher(PointCloud2, 'points', 5)
    rec = np.zeros((16, 2000), dtype=[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('rgb', '<u4')])
    rec['x'] = np.arange(2000)[None, :] * 0.01
    rec['y'] = np.arange(16)[:, None]
    rec['z'] = 1.5
    rec['rgb'] = 0x00ff8000
    rec['x'][3, :] = np.nan
    msg = PointCloud2(height=16, width=2000, is_bigendian=False, point_step=16, row_step=16 * 2000, is_dense=False,
                      fields=[PointField(name=n, offset=4 * i, datatype=7 if n != 'rgb' else 6, count=1)
                              for i, n in enumerate(('x', 'y', 'z', 'rgb'))])
    msg.header.frame_id = 'lidar'
    msg.data = rec.tobytes()
    timer = node.create_timer(0.1, lambda: pub.publish(msg))
    caller.executor.add_node(node)
    node.cloud = msg
    yield node
    caller.executor.remove_node(node)
    node.destroy_timer(timer)
    node.destroy_node()


async def test_a_real_clouds_points_thinned_for_a_page(gateway, lidar):
    import base64

    import numpy as np
    with client(gateway) as ros:
        wait_for(lambda: '/bot/points' in ros.get_topics(), 20)
        clouds = []
        ros.on('/bot/points', clouds.append)
        ros.send_on_ready(roslibpy.Message({'op': 'subscribe', 'id': 'thin', 'topic': '/bot/points',
                                            'type': 'sensor_msgs/msg/PointCloud2', 'points': 1000}))
        wait_for(lambda: clouds, 20)
        cloud = clouds[0]['msg'] if 'msg' in clouds[0] else clouds[0]
        assert (cloud['height'], cloud['width'], cloud['point_step']) == (1, 1000, 16)
        assert [f['name'] for f in cloud['fields']] == ['x', 'y', 'z', 'rgb'] and cloud['header']['frame_id'] == 'lidar'
        raw = np.frombuffer(base64.b64decode(cloud['data']), np.uint8).reshape(-1, 16)
        xyz = raw[:, :12].copy().view('<f4').reshape(-1, 3)
        assert np.isfinite(xyz).all() and (xyz[:, 2] == 1.5).all() and 3.0 not in xyz[:, 1]   # row 3 had no returns
        assert (raw[:, 12:].copy().view('<u4').ravel() == 0x00ff8000).all()


async def test_a_real_topics_rate_and_bandwidth_from_its_cdr(gateway, lidar):
    """/rosgate/topic_stats on the rclpy backend: each message's size is its CDR as received."""
    from rclpy.serialization import serialize_message
    size = len(serialize_message(lidar.cloud))
    with client(gateway) as ros:
        wait_for(lambda: '/bot/points' in ros.get_topics(), 20)
        stats = roslibpy.Service(ros, '/rosgate/topic_stats', 'rosgate_msgs/srv/TopicStatistics')

        def measured():
            v = stats.call(roslibpy.ServiceRequest({'topics': ['/bot/points']}), timeout=10)
            return v if v['rates'][0] > 0 and v['windows'][0] >= 1 else None
        v = wait_for(measured, 30, 0.3)
        assert v['bandwidths'][0] == pytest.approx(v['rates'][0] * size, rel=1e-6), (v, size)
