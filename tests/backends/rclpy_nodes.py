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


class OwnContextNode:
    """A node in an rclpy context of its own (its own DDS participant, as another process would
    be): make its endpoints on ``self.node``, then start() spins it in a thread until stop()."""

    def __init__(self, name: str):
        import rclpy
        from rclpy.context import Context
        from rclpy.signals import SignalHandlerOptions
        self.context = Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name, context=self.context)

    def start(self) -> None:
        from rclpy.executors import SingleThreadedExecutor
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        try:
            self.executor.spin()
        except Exception:     # the context shut down under it
            pass

    def stop(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()
        self.thread.join(5)


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
        adder.create_service(self._add, '/add_two_ints', self._add_two_ints)

        fib = rclpy.create_node('fibonacci_action_server', context=self.context,
                                allow_undeclared_parameters=True)
        fib.declare_parameter('step_interval', self.step_interval)
        self._group, self._fib_node = group, fib
        self._server = ActionServer(fib, self._fib, '/fibonacci', self._fibonacci, callback_group=group,
                                    cancel_callback=lambda goal: CancelResponse.ACCEPT)
        self.nodes = [talker, adder, fib]
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        for node in self.nodes:
            self.executor.add_node(node)
        self.thread = threading.Thread(target=self.executor.spin, name='helper-nodes', daemon=True)
        self.thread.start()

    def _add_two_ints(self, request, response):
        if self.add_type.endswith('AddTwoInts'):
            response.sum = request.a + request.b
        else:
            response.int64_value = request.int64_value + request.int32_value
        return response

    def _fibonacci(self, goal_handle):
        Fibonacci, sequence = self._fib, [0, 1]
        goal_handle.publish_feedback(Fibonacci.Feedback(sequence=sequence))
        for _ in range(1, goal_handle.request.order):
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
                return Fibonacci.Result(sequence=sequence)
            time.sleep(self._fib_node.get_parameter('step_interval').value)
            sequence.append(sequence[-1] + sequence[-2])
            goal_handle.publish_feedback(Fibonacci.Feedback(sequence=sequence))
        goal_handle.succeed()
        return Fibonacci.Result(sequence=sequence)

    def late_server(self, kind: str, name: str):
        """A node created now that serves name ('service': the adder, 'action': Fibonacci), as a
        node started after the gateway would; returns a function that destroys it."""
        import rclpy
        from rclpy.action import ActionServer

        node = rclpy.create_node(f'late_{len(self.nodes)}', context=self.context)
        if kind == 'service':
            node.create_service(self._add, name, self._add_two_ints)
            server = None
        else:
            server = ActionServer(node, self._fib, name, self._fibonacci, callback_group=self._group)
        self.nodes.append(node)
        self.executor.add_node(node)

        def stop() -> None:
            self.executor.remove_node(node)
            if server is not None:
                server.destroy()
            node.destroy_node()
            self.nodes.remove(node)
        return stop

    def stop(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self._server.destroy()
        for node in self.nodes:
            node.destroy_node()
        self.context.try_shutdown()
        self.thread.join(timeout=2.0)


class RosCaller:
    """A ROS node of its own context that calls a service and sends goals (as another process
    would), on a SingleThreadedExecutor in its own thread. Its coroutines poll rclpy futures."""

    def __init__(self):
        self.add_type, self._add = find('add')
        self.fib_type, self._fib = find('fibonacci')
        self._clients: dict = {}

    def start(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('ros_caller', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, name='ros-caller', daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self.context.try_shutdown()
        self.thread.join(timeout=2.0)

    def _client(self, name: str):
        client = self._clients.get(name)
        if client is None:
            client = self._clients[name] = self.node.create_client(self._add, name)
        return client

    def _action_client(self, name: str):
        from rclpy.action import ActionClient

        client = self._clients.get(name)
        if client is None:
            client = self._clients[name] = ActionClient(self.node, self._fib, name)
        return client

    def string_publisher(self, topic: str, depth: int = 1000):
        """``publish(text)`` on topic as std_msgs/String (from any thread: rcl allows it)."""
        from std_msgs.msg import String

        pub = self.node.create_publisher(String, topic, depth)
        return lambda text: pub.publish(String(data=text)), pub.get_subscription_count

    def publisher(self, cls, topic: str, depth: int = 1000):
        """``publish(msg)`` of a message class on topic."""
        return self.node.create_publisher(cls, topic, depth).publish

    def raw_listener(self, cls, topic: str, depth: int = 1000) -> list[bytes]:
        """The CDR of every message on topic as DDS delivers it, appended as it comes."""
        got: list[bytes] = []
        self.node.create_subscription(cls, topic, got.append, depth, raw=True)
        return got

    def ready(self, service: str, action: str) -> bool:
        return self._client(service).service_is_ready() and self._action_client(action).server_is_ready()

    async def call(self, name: str, request: dict, timeout: float = 10.0) -> dict:
        """The response as a dict of its fields."""
        response = await _done(self._client(name).call_async(self._add.Request(**request)), timeout)
        return {field: getattr(response, field) for field in response.get_fields_and_field_types()}

    async def goal(self, name: str, order: int, timeout: float = 10.0):
        """(result, feedback sequences) of one Fibonacci goal."""
        feedback = []
        handle = await _done(self._action_client(name).send_goal_async(
            self._fib.Goal(order=order), feedback_callback=lambda m: feedback.append(list(m.feedback.sequence))),
            timeout)
        assert handle.accepted
        response = await _done(handle.get_result_async(), timeout)
        return response.result, feedback


async def _done(future, timeout: float):
    """The result of an rclpy Future, awaited from asyncio: its done callback (on the executor's
    thread) settles an asyncio future on this loop."""
    import asyncio

    loop = asyncio.get_running_loop()
    settled = loop.create_future()

    def hop(_future) -> None:
        loop.call_soon_threadsafe(lambda: settled.done() or settled.set_result(None))

    future.add_done_callback(hop)
    try:
        await asyncio.wait_for(settled, timeout)
    except asyncio.TimeoutError:
        raise AssertionError(f'no answer within {timeout} s') from None
    return future.result()
