"""ROS 2 nodes written in rclpy, the counterparts of the sim's demo nodes, for the contract suite.

``/talker`` publishes ``/chatter``; ``/add_two_ints_server`` serves ``/add_two_ints``;
``/fibonacci_action_server`` serves ``/fibonacci`` one step per ``step_interval`` (a parameter),
with feedback and cancel, as in the ROS 2 tutorials. They run in their own rclpy context (their
own DDS participant, as another process would be) with their own executor thread.

example_interfaces is preferred; where it is not installed, test_msgs supplies a Fibonacci
action of the same shape and BasicTypes stands in for AddTwoInts (a: int64_value,
b: int32_value, sum: int64_value).
"""

from __future__ import annotations

import importlib
import threading
import time

CHOICES = {
    'add': [('example_interfaces', 'srv', 'AddTwoInts'), ('test_msgs', 'srv', 'BasicTypes')],
    'fibonacci': [('example_interfaces', 'action', 'Fibonacci'), ('test_msgs', 'action', 'Fibonacci')],
}


def find(kind: str):
    """(full type name, class) of the first installed choice."""
    for pkg, sub, name in CHOICES[kind]:
        try:
            return f'{pkg}/{sub}/{name}', getattr(importlib.import_module(f'{pkg}.{sub}'), name)
        except (ImportError, AttributeError):
            continue
    raise RuntimeError(f'none of {CHOICES[kind]} is installed')


class HelperNodes:
    def __init__(self, step_interval: float = 0.05):
        self.add_type, self._add = find('add')
        self.fib_type, self._fib = find('fibonacci')
        self.step_interval = step_interval

    # request/response fields of the adder
    def add_request(self, a: int, b: int) -> dict:
        return {'a': a, 'b': b} if self.add_type.endswith('AddTwoInts') else {'int64_value': a, 'int32_value': b}

    def add_sum(self, response: dict) -> int:
        return response['sum'] if self.add_type.endswith('AddTwoInts') else response['int64_value']

    def start(self) -> None:
        import rclpy
        from rclpy.action import ActionServer, CancelResponse
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.context import Context
        from rclpy.executors import MultiThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        from std_msgs.msg import String

        self.context = Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        group = ReentrantCallbackGroup()

        talker = rclpy.create_node('talker', context=self.context)
        chatter = talker.create_publisher(String, '/chatter', 10)
        count = iter(range(1, 2**62))
        talker.create_timer(0.1, lambda: chatter.publish(String(data=f'Hello World: {next(count)}')))

        adder = rclpy.create_node('add_two_ints_server', context=self.context)
        two_ints = self.add_type.endswith('AddTwoInts')

        def add(request, response):
            if two_ints:
                response.sum = request.a + request.b
            else:
                response.int64_value = request.int64_value + request.int32_value
            return response

        adder.create_service(self._add, '/add_two_ints', add)

        fib = rclpy.create_node('fibonacci_action_server', context=self.context,
                                allow_undeclared_parameters=True)
        fib.declare_parameter('step_interval', self.step_interval)
        Fibonacci = self._fib

        def execute(goal_handle):
            sequence = [0, 1]
            goal_handle.publish_feedback(Fibonacci.Feedback(sequence=sequence))
            for _ in range(1, goal_handle.request.order):
                if goal_handle.is_cancel_requested:
                    goal_handle.canceled()
                    return Fibonacci.Result(sequence=sequence)
                time.sleep(fib.get_parameter('step_interval').value)
                sequence.append(sequence[-1] + sequence[-2])
                goal_handle.publish_feedback(Fibonacci.Feedback(sequence=sequence))
            goal_handle.succeed()
            return Fibonacci.Result(sequence=sequence)

        self._server = ActionServer(fib, Fibonacci, '/fibonacci', execute, callback_group=group,
                                    cancel_callback=lambda goal: CancelResponse.ACCEPT)
        self.nodes = [talker, adder, fib]
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        for node in self.nodes:
            self.executor.add_node(node)
        self.thread = threading.Thread(target=self.executor.spin, name='helper-nodes', daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self._server.destroy()
        for node in self.nodes:
            node.destroy_node()
        self.context.try_shutdown()
        self.thread.join(timeout=2.0)
