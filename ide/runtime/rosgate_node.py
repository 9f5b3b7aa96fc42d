"""The runtime of a ROS 2 node made from blocks (ide/generators/node.js): the program API of the
roslibpy script (rosgate_runtime.Runtime) on rclpy, so the same blocks mean the same thing.

The node's program runs in a thread of its own while a MultiThreadedExecutor spins the node in the
main thread: a waiting block (sleep, a service call, a goal, "wait for a message") waits in the
program's thread, never inside a callback, so subscriptions, timers, clients and servers keep being
served. A subscription callback only stores the message and hands it to the block handler's own
thread (as the script's on_message does), so a handler with a sleep block holds no executor thread.
Ctrl-C (SIGINT) or SIGTERM stops the program and publishes zero velocity on every velocity topic the
program used, and waits (at most 2 s) until its subscribers acknowledged it before the node goes.
"""
import importlib
import queue
import re
import signal
import sys
import threading
import time
import traceback

import rclpy
from rclpy.action import ActionClient, ActionServer
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.duration import Duration
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.task import Future
from rclpy.signals import SignalHandlerOptions

from .rosgate_runtime import Event, RosError, Runtime, StopProgram, is_velocity_type, zero_velocity
from .rosgate_runtime import *  # noqa: F401,F403 -- the blocks' helpers: field, pick, yaw, range_at ...

DEPTH = 10            # the queue depth of every publisher and subscription
READY_TIMEOUT = 10.0  # seconds a service or action server has to appear


def interface(t):
    """The class of a ROS type: 'geometry_msgs/msg/Twist' (or 'geometry_msgs/Twist') -> Twist."""
    if not isinstance(t, str):
        return t
    parts = t.split("/")
    pkg, kind, name = (parts[0], "msg", parts[1]) if len(parts) == 2 else parts
    return getattr(importlib.import_module("%s.%s" % (pkg, kind)), name)


SEQUENCE = re.compile(r"^sequence<(.+?)(?:, *\d+)?>$|^(.+)\[\d+\]$")
INTEGER = re.compile(r"^u?int(8|16|32|64)$|^(octet|byte|char)$")


def _convert(ftype, value):
    m = SEQUENCE.match(ftype)
    if m:
        return [_convert(m.group(1) or m.group(2), v) for v in value]
    if "/" in ftype:
        return to_message(interface(ftype), value)
    if ftype in ("float", "double"):
        return float(value)
    if INTEGER.match(ftype):
        return int(value)
    if ftype == "boolean":
        return bool(value)
    return value


def to_message(cls, values):
    """A message of class cls from the blocks' dict (as rosbridge JSON: nested dicts, lists)."""
    msg = cls()
    fields = cls.get_fields_and_field_types()
    for key, value in (values or {}).items():
        if key not in fields:
            raise RosError("%s has no field '%s'" % (cls.__name__, key))
        setattr(msg, key, _convert(fields[key], value))
    return msg


def to_dict(msg):
    """The blocks' view of a message: nested dicts and lists of plain numbers, as rosbridge sends."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {k: to_dict(getattr(msg, k)) for k in msg.get_fields_and_field_types()}
    if isinstance(msg, (bytes, bytearray)):
        return list(msg)
    if hasattr(msg, "tolist"):          # numpy and array.array fields
        return msg.tolist()
    if isinstance(msg, (list, tuple)):
        return [to_dict(x) for x in msg]
    return msg


class BlockNode(Node):
    """A node that runs a block program: program() is the blocks' main stack."""

    # the program control of the script's Runtime, the same functions (they use stopped, error,
    # t0, handlers, _lock, _subs and _subscribe only)
    elapsed = Runtime.elapsed
    sleep = Runtime.sleep
    log = Runtime.log
    _check = Runtime._check
    _wait = Runtime._wait
    fail = Runtime.fail
    _handled = Runtime._handled
    on_message = Runtime.on_message
    _serial = Runtime._serial
    wait_for_message = Runtime.wait_for_message
    latest = Runtime.latest
    drive = Runtime.drive
    move = Runtime.move
    turn = Runtime.turn
    _served = Runtime._served
    _deliver = Runtime._deliver
    _program_state = Runtime._program_state
    _subscribe = Runtime._subscribe

    def __init__(self, name, namespace=""):
        super().__init__(name, namespace=namespace or "")
        self._program_state()
        self._rg_pubs = {}
        self._rg_clients = {}
        self._rg_actions = {}
        self.group = ReentrantCallbackGroup()

    def program(self):
        """The blocks' program; a generated node overrides it."""

    def ns(self, name):
        """A robot block's name, relative: in the node's namespace (ros2 run ... -r __ns:=/s07)."""
        return str(name).lstrip("/") or "/"

    # ---- the node's publishers, subscriptions and clients, made once per name
    def publisher(self, topic, t):
        with self._lock:
            if topic not in self._rg_pubs:
                self._rg_pubs[topic] = (self.create_publisher(interface(t), topic, DEPTH), interface(t))
            return self._rg_pubs[topic]

    def subscription(self, topic, t):
        self._subscribe(topic, t)

    def service_client(self, service, t):
        with self._lock:
            if service not in self._rg_clients:
                self._rg_clients[service] = (self.create_client(interface(t), service, callback_group=self.group), interface(t))
            return self._rg_clients[service]

    def action_client(self, action, t):
        with self._lock:
            if action not in self._rg_actions:
                self._rg_actions[action] = (ActionClient(self, interface(t), action, callback_group=self.group), interface(t))
            return self._rg_actions[action]

    # ---- topics
    def publish(self, topic, t, msg):
        self._check()
        pub, cls = self.publisher(topic, t)
        if is_velocity_type(t):
            self._velocity[topic] = t
        pub.publish(to_message(cls, msg))

    def _listen(self, topic, t, sub):
        self.create_subscription(interface(t), topic, lambda m: self._deliver(sub, to_dict(m)), DEPTH,
                                 callback_group=self.group)

    # ---- services and actions
    def _ready(self, is_ready, what):
        end = time.monotonic() + READY_TIMEOUT
        while not is_ready():
            self._check()
            if time.monotonic() > end:
                raise RosError("%s is not available (waited %g s)" % (what, READY_TIMEOUT))
            time.sleep(0.05)

    def _result(self, future, timeout, what):
        done = Event()
        future.add_done_callback(lambda _: done.set())
        self._wait(done, timeout, what)
        return future.result()

    def call_service(self, service, t, args=None, timeout=0):
        self._check()
        client, cls = self.service_client(service, t)
        self._ready(client.service_is_ready, "service " + service)
        answer = self._result(client.call_async(to_message(cls.Request, args)),
                              float(timeout) if timeout else 30.0, "service " + service)
        return to_dict(answer)

    def send_goal(self, action, t, goal=None, on_feedback=None):
        """Sends a goal and waits for its result; on_feedback runs, in order, in a thread of its
        own and has handled every feedback before the result is returned."""
        self._check()
        client, cls = self.action_client(action, t)
        self._ready(client.server_is_ready, "action " + action)
        feedbacks = queue.Queue()

        def worker():
            while True:
                values = feedbacks.get()
                if values is None or self.stopped.is_set() or not self._handled(on_feedback, values):
                    return

        thread = threading.Thread(target=worker, daemon=True) if on_feedback is not None else None
        if thread is not None:
            thread.start()
        sent = client.send_goal_async(to_message(cls.Goal, goal),
                                      feedback_callback=lambda fb: feedbacks.put(to_dict(fb.feedback)))
        handle = self._result(sent, READY_TIMEOUT, "action " + action)
        if not handle.accepted:
            feedbacks.put(None)
            raise RosError("action %s refused the goal" % action)
        self._goals[id(handle)] = (action, handle)
        try:
            res = self._result(handle.get_result_async(), 0, "action " + action)
        finally:
            self._goals.pop(id(handle), None)
            feedbacks.put(None)
        if res.status != 4:
            what = {5: "was canceled", 6: "was aborted"}.get(res.status, "ended with status %s" % res.status)
            raise RosError("action %s %s" % (action, what))
        while thread is not None and thread.is_alive():
            thread.join(0.05)
            self._check()
        return to_dict(res.result)

    def cancel(self, action=None):
        for name, handle in list(self._goals.values()):
            if action is None or name == action:
                handle.cancel_goal_async()

    # ---- "every N s": a ROS timer
    def every(self, seconds, handler):
        """A timer of the node: its callback only wakes a thread of the block's own, which runs
        handler() (a tick that comes while it still runs is skipped)."""
        tick = Event()

        def worker():
            while not self.stopped.is_set():
                if tick.wait(0.1):
                    tick.clear()
                    if not self._handled(lambda _: handler(), None):
                        return
        self.handlers += 1
        self.create_timer(max(0.01, float(seconds or 0)), tick.set, callback_group=self.group)
        threading.Thread(target=worker, daemon=True).start()

    # ---- servers: the program's own services and actions
    async def _in_thread(self, fn, *args):
        """fn(*args) in a thread of its own, awaited by the executor's callback (a coroutine): a
        server whose blocks wait holds no executor thread. (answer, True) or (None, False)."""
        future = Future(executor=self.executor)
        threading.Thread(target=lambda: future.set_result(self._served(fn, *args)), daemon=True).start()
        return await future

    def serve_service(self, service, t, handler):
        self._check()
        cls = interface(t)

        async def callback(request, response):
            values, ok = await self._in_thread(handler, to_dict(request))
            return to_message(cls.Response, values) if ok else response

        self.handlers += 1
        self.create_service(cls, service, callback, callback_group=self.group)

    def serve_action(self, action, t, handler):
        self._check()
        cls = interface(t)

        async def execute(goal_handle):
            values, ok = await self._in_thread(handler, to_dict(goal_handle.request), (goal_handle, cls))
            if not ok:
                goal_handle.abort()
                return cls.Result()
            goal_handle.succeed()
            return to_message(cls.Result, values)

        self.handlers += 1
        ActionServer(self, cls, action, execute_callback=execute, callback_group=self.group)

    def action_feedback(self, goal_handle, values):
        if goal_handle is None:
            raise RosError("'send feedback' works inside 'serve action' only")
        self._check()
        handle, cls = goal_handle
        handle.publish_feedback(to_message(cls.Feedback, values))

    # ---- the robot
    def stop_robot(self):
        for topic, t in list(self._velocity.items()):
            pub, cls = self._rg_pubs[topic]
            pub.publish(to_message(cls, zero_velocity(t)))

    def stop_and_wait(self, timeout=2.0):
        """Zero velocity, acknowledged by the subscribers (reliable QoS) or timeout seconds gone."""
        self.stop_robot()
        for topic in list(self._velocity):
            self._rg_pubs[topic][0].wait_for_all_acked(Duration(seconds=timeout))

    def _run_program(self):
        try:
            self.program()
        except StopProgram:
            pass
        except Exception as e:
            traceback.print_exc()
            self.fail(e)


def _interrupt(*_):
    raise KeyboardInterrupt()


def run_node(cls, args=None):
    """rclpy.init, the node, its program in a thread of its own while a MultiThreadedExecutor
    spins; until the program ends (and its message handlers with Ctrl-C), then zero velocity.
    rclpy's own signal handler is off: it would shut the context down before the zero velocity
    could be published."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _interrupt)
    node = cls()
    sys.modules[cls.__module__].rt = node    # the blocks' functions call rt.*
    executor = MultiThreadedExecutor()
    executor.add_node(node)
    program = threading.Thread(target=node._run_program, name="program", daemon=True)
    program.start()
    try:
        while not node.stopped.is_set() and (program.is_alive() or node.handlers):
            executor.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        node.stopped.set()
        program.join(2.0)
        try:
            node.stop_and_wait()
            node.cancel()
        finally:
            executor.shutdown()
            node.destroy_node()
            rclpy.try_shutdown()
    return 1 if node.error is not None else 0
