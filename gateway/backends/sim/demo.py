"""Demo nodes of the sim graph, as in the ROS 2 tutorials: AddTwoInts, Fibonacci, a talker."""

from __future__ import annotations

import asyncio

from ..base import STATUS_CANCELED, BackendError
from .graph import Graph, SimServerGoal

INT64 = (-(2**63), 2**63 - 1)


def start_demo_nodes(graph: Graph, *, talker: bool = False, fibonacci_interval: float = 1.0) -> None:
    adder = graph.node('add_two_ints_server')
    adder.yields = True     # a program serving /add_two_ints (the ROS 2 tutorial's) takes it over meanwhile

    def add_two_ints(request):
        total = request['a'] + request['b']
        if not INT64[0] <= total <= INT64[1]:
            raise BackendError('sum overflows int64')
        return {'sum': total}

    adder.create_service('/add_two_ints', 'example_interfaces/srv/AddTwoInts', add_two_ints)

    fib = graph.node('fibonacci_action_server')
    fib.declare_parameter('step_interval', float(fibonacci_interval))

    async def fibonacci(goal: SimServerGoal):
        order = goal.request['order']
        if not 0 <= order <= 46:  # F(47) overflows the int32 elements
            raise BackendError('order must be between 0 and 46')
        sequence = [0, 1][:order + 1] if order < 2 else [0, 1]
        goal.publish_feedback({'sequence': list(sequence)})
        for _ in range(1, order):
            if goal.cancel_requested:
                goal.finish(STATUS_CANCELED, {'sequence': sequence})
                return {'sequence': sequence}
            await asyncio.sleep(fib.params['step_interval'])
            sequence.append(sequence[-1] + sequence[-2])
            goal.publish_feedback({'sequence': list(sequence)})
        return {'sequence': sequence}

    fib.create_simple_action_server('/fibonacci', 'example_interfaces/action/Fibonacci', fibonacci)

    if talker:
        node = graph.node('talker')
        pub = node.create_publisher('/chatter', 'std_msgs/msg/String')
        count = iter(range(1, 2**62))
        node.create_timer(1.0, lambda: pub.publish({'data': f'Hello World: {next(count)}'}))
