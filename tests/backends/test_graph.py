"""Graph introspection and type descriptions."""

from __future__ import annotations

import time

import pytest

from gateway.backends.base import BackendError, QoS

from tests.support.wait import until

pytestmark = pytest.mark.asyncio(loop_scope='session')


async def test_nodes(world):
    nodes = world.backend.nodes()
    for node in (world.backend.node_name, '/add_two_ints_server', '/fibonacci_action_server'):
        assert node in nodes


async def test_topic_endpoints_follow_create_and_destroy(world, topic):
    """The graph follows creation and destruction (eventually: a ROS graph is discovered)."""
    backend, me = world.backend, world.backend.node_name
    pub = backend.create_publisher(topic, 'std_msgs/msg/String', QoS())
    await until(lambda: (topic, 'std_msgs/msg/String') in backend.topics(), what='topic listed')
    await until(lambda: backend.publishers(topic) == [me], what='publisher listed')
    await until(lambda: topic in backend.node_info(me).publishing, what='node publishing')
    sub = backend.subscribe(topic, 'std_msgs/msg/String', lambda msg: None)
    await until(lambda: backend.subscribers(topic) == [me], what='subscriber listed')
    await until(lambda: topic in backend.node_info(me).subscribing, what='node subscribing')
    pub.destroy()
    await until(lambda: backend.publishers(topic) == [], what='publisher gone')
    await until(lambda: topic not in backend.node_info(me).publishing, what='node not publishing')
    sub.destroy()
    await until(lambda: topic not in dict(backend.topics()), what='topic gone')
    await until(lambda: topic not in backend.node_info(me).subscribing, what='node not subscribing')


async def test_a_subscription_alone_lists_its_topic_with_no_publisher(world, topic):
    """As ``ros2 topic list`` does (rcl's graph lists a topic with any endpoint): a page that looks
    for a topic the robot does not have puts the name on the graph while it looks. So the pages
    subscribe only to what has a publisher, and the sim does as ROS 2 does."""
    backend, me = world.backend, world.backend.node_name
    sub = backend.subscribe(topic, 'sensor_msgs/msg/BatteryState', lambda msg: None)
    await until(lambda: (topic, 'sensor_msgs/msg/BatteryState') in backend.topics(), what='topic listed')
    await until(lambda: backend.subscribers(topic) == [me], what='subscriber listed')
    assert backend.publishers(topic) == []
    sub.destroy()
    await until(lambda: topic not in dict(backend.topics()), what='topic gone with its subscriber')


async def test_services_and_providers(world):
    backend = world.backend
    assert dict(backend.services())['/add_two_ints'] == world.add_type
    assert backend.service_providers('/add_two_ints') == ['/add_two_ints_server']
    assert '/add_two_ints' in backend.node_info('/add_two_ints_server').services
    assert backend.service_providers('/no_such_service') == []


async def test_actions_listed(world):
    assert dict(world.backend.actions())['/fibonacci'] == world.fib_type


async def test_unknown_node(world):
    with pytest.raises(BackendError):
        world.backend.node_info('/no_such_node')


async def test_now(world):
    sec, nanosec = world.backend.now()
    assert abs(sec + nanosec / 1e9 - time.time()) < 5
    assert 0 <= nanosec < 1_000_000_000


async def test_msg_defs(world):
    backend = world.backend
    twist = backend.msg_def('geometry_msgs/Twist')
    assert twist.type == 'geometry_msgs/msg/Twist'
    assert [(f.name, f.type) for f in twist.fields] == [
        ('linear', 'geometry_msgs/msg/Vector3'), ('angular', 'geometry_msgs/msg/Vector3')]
    scan = {f.name: f for f in backend.msg_def('sensor_msgs/msg/LaserScan').fields}
    assert (scan['ranges'].type, scan['ranges'].array) == ('float32', 0)
    image = {f.name: f for f in backend.msg_def('sensor_msgs/msg/Image').fields}
    assert image['data'].is_bytes
    status = backend.msg_def('action_msgs/msg/GoalStatus')
    assert ('STATUS_SUCCEEDED', 4) in [(c[0], c[2]) for c in status.constants]
    typedefs = backend.typedefs(twist)
    assert [t['type'] for t in typedefs] == ['geometry_msgs/Twist', 'geometry_msgs/Vector3']
    assert typedefs[0]['fieldnames'] == ['linear', 'angular']
    assert 'MSG: geometry_msgs/Vector3' in backend.full_text(twist)
    with pytest.raises(LookupError):
        backend.msg_def('no_such_msgs/msg/Nothing')


async def test_srv_and_action_defs(world):
    backend = world.backend
    srv = backend.srv_def(world.add_type)
    assert srv.type == world.add_type
    assert set(world.add_operands({f.name: 1 for f in srv.request.fields}))
    action = backend.action_def(world.fib_type)
    assert [f.name for f in action.goal.fields] == ['order']
    assert [(f.name, f.type, f.array) for f in action.result.fields] == [('sequence', 'int32', 0)]
    assert [f.name for f in action.feedback.fields] == ['sequence']


async def test_interfaces(world):
    names = world.backend.interfaces()
    assert 'std_msgs/msg/String' in names
    assert 'sensor_msgs/msg/LaserScan' in names
    assert world.fib_type in names


@pytest.mark.parametrize('type', [
    'std_msgs/msg/Header', 'geometry_msgs/msg/PoseWithCovarianceStamped', 'sensor_msgs/msg/Image',
    'sensor_msgs/msg/LaserScan', 'sensor_msgs/msg/CameraInfo', 'sensor_msgs/msg/JointState',
    'sensor_msgs/msg/PointCloud2', 'sensor_msgs/msg/Imu', 'std_msgs/msg/Float64MultiArray',
])
async def test_fields_match_jazzy(world, type):
    """Every backend describes common messages exactly as the Jazzy definitions do."""
    from protocol.msgdefs import Definitions
    jazzy = Definitions.jazzy().msg(type)
    mine = world.backend.msg_def(type)
    assert mine.fields == jazzy.fields
    assert [(c[0], c[2]) for c in mine.constants] == [(c[0], c[2]) for c in jazzy.constants]
