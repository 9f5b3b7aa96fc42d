"""The backend contract suite runs once per backend that imports: sim always, rclpy where it imports.

For rclpy the counterparts of the sim's demo nodes (tests/backends/rclpy_nodes.py) run in this
process, in a context of their own, on a ROS domain of their own limited to this host.
"""

from __future__ import annotations

import os
import random
import uuid
from dataclasses import dataclass

import pytest
import pytest_asyncio

from tests.support.contract import rclpy_missing
from tests.support.wait import until

SIM_STEP = 0.05   # seconds per Fibonacci step, both backends


@dataclass
class World:
    """A started backend plus the names and types of the demo nodes it can reach."""
    backend: object
    add_type: str
    fib_type: str
    helpers: object = None

    def add_request(self, a: int, b: int) -> dict:
        return self.helpers.add_request(a, b) if self.helpers else {'a': a, 'b': b}

    def add_sum(self, response: dict) -> int:
        return self.helpers.add_sum(response) if self.helpers else response['sum']

    def add_operands(self, request: dict) -> tuple[int, int]:
        if 'a' in request:
            return request['a'], request['b']
        return request['int64_value'], request['int32_value']

    def add_response(self, total: int) -> dict:
        if self.helpers and not self.add_type.endswith('AddTwoInts'):
            return {'int64_value': total}
        return {'sum': total}

    def late_server(self, kind: str, name: str):
        """A node created now serving name ('service': the adder, 'action': Fibonacci), as one
        started after the gateway; returns a function that destroys it."""
        if self.helpers:
            return self.helpers.late_server(kind, name)
        from gateway.backends.sim.graph import SimServerGoal

        node = self.backend.graph.node(f'late_{uuid.uuid4().hex[:8]}')
        if kind == 'service':
            node.create_service(name, self.add_type, lambda r: {'sum': r['a'] + r['b']})
        else:
            async def fibonacci(goal: SimServerGoal) -> dict:
                sequence = [0, 1]
                for _ in range(1, goal.request['order']):
                    sequence.append(sequence[-1] + sequence[-2])
                return {'sequence': sequence}
            node.create_simple_action_server(name, self.fib_type, fibonacci)
        return node.destroy

    def full(self, type: str, partial: dict) -> dict:
        """A complete message: ``partial`` with every other field at its default."""
        from protocol.convert import from_json
        return from_json(self.backend.defs, self.backend.msg_def(type), partial)


@pytest.fixture(scope='session')
def rclpy_helpers():
    os.environ['ROS_DOMAIN_ID'] = str(random.randint(1, 100))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    from .rclpy_nodes import HelperNodes
    helpers = HelperNodes(step_interval=SIM_STEP)
    helpers.start()
    yield helpers
    helpers.stop()


@pytest_asyncio.fixture(loop_scope='session')
async def caller(rclpy_helpers):
    """A plain rclpy node of its own context: calls services and actions, publishes."""
    from .rclpy_nodes import RosCaller
    ros = RosCaller()
    ros.start()
    yield ros
    ros.stop()


@pytest_asyncio.fixture(scope='session', loop_scope='session', params=['sim', 'rclpy'])
async def world(request):
    """One started backend per kind, shared by the suite (tests use fresh names)."""
    if request.param == 'sim':
        from gateway.backends.sim import SimBackend
        backend = SimBackend(demo=True, talker=True, fibonacci_interval=SIM_STEP)
        await backend.start()
        w = World(backend, 'example_interfaces/srv/AddTwoInts', 'example_interfaces/action/Fibonacci')
    else:
        missing = rclpy_missing()
        if missing:
            pytest.skip(f'rclpy does not import here: {missing}')
        helpers = request.getfixturevalue('rclpy_helpers')
        from gateway.backends.rclpy.backend import RclpyBackend
        backend = RclpyBackend(ros_args=[], service_timeout=5.0)
        await backend.start()
        w = World(backend, helpers.add_type, helpers.fib_type, helpers)
        nodes = {'/talker', '/add_two_ints_server', '/fibonacci_action_server'}
        await until(lambda: '/add_two_ints' in dict(backend.services())
                    and '/fibonacci' in dict(backend.actions())
                    and nodes <= set(backend.nodes()), timeout=15, what='helper nodes discovered')
    try:
        yield w
    finally:
        await backend.stop()


@pytest.fixture
def backend(world):
    return world.backend


@pytest.fixture
def topic():
    return f'/contract_{uuid.uuid4().hex[:10]}'
