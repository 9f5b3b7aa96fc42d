"""Driver-lease stations on a real multi-robot graph: the top namespaces of the nodes that
subscribe to a velocity topic inside them (what --exclusive-control leases one by one and what
/class shows), found the same way on every backend."""

from __future__ import annotations

import uuid

import pytest

from gateway.rules.stations import find_stations

from tests.support.wait import until

pytestmark = pytest.mark.asyncio(loop_scope='session')
TWIST = 'geometry_msgs/msg/Twist'


class SimRobots:
    def __init__(self, backend, namespaces):
        self.nodes = [backend.graph.node('base_controller', ns) for ns in namespaces]
        for node in self.nodes:
            node.create_subscription('cmd_vel', TWIST, lambda msg: None)

    def stop(self):
        for node in self.nodes:
            node.destroy()


class RclpyRobots:
    """Two robot drivers in their own rclpy context, as other processes on the robot would be."""

    def __init__(self, namespaces):
        import rclpy
        from geometry_msgs.msg import Twist
        from rclpy.context import Context
        from rclpy.signals import SignalHandlerOptions
        self.context = Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.nodes = []
        for ns in namespaces:
            node = rclpy.create_node('base_controller', namespace=ns, context=self.context)
            node.create_subscription(Twist, 'cmd_vel', lambda msg: None, 10)
            self.nodes.append(node)

    def stop(self):
        for node in self.nodes:
            node.destroy_node()
        self.context.try_shutdown()


async def test_stations_from_robot_namespaces(world):
    backend = world.backend
    names = [f'/robot_{uuid.uuid4().hex[:6]}' for _ in range(2)]
    robots = (SimRobots(backend, names) if hasattr(backend, 'graph')
              else RclpyRobots(names))
    try:
        types = frozenset({TWIST, 'geometry_msgs/msg/TwistStamped'})
        found = await until(lambda: set(names) <= set(find_stations(backend, types)) and find_stations(backend, types),
                            timeout=15, what='both robots found as stations')
        assert [ns for ns in found if ns.startswith('/robot_')] == sorted(names)
    finally:
        robots.stop()
