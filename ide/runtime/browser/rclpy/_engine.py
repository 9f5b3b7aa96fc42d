"""What rclpy's C layer and the middleware are on a ROS 2 machine, in the IDE page: the program's
entities as rosbridge ops over the page's connection (rosgate_browser), and the gateway's messages
for them, queued for the executor that spins their node.

Everything a program makes goes through the gateway as the page's own ops, under the gateway's
rules (name globs, the driver lease, clamps), and Stop ends the worker: the page then zeroes every
velocity topic the program published to, cancels its goals and ends its subscriptions and
advertisements (ide/js/run/pyrun.js), as it does for any Python program of the page.

One thread: a callback runs only when an executor spins (rclpy.spin, spin_once ...), and a wait of
the program (time.sleep, a blocking call, an executor's wait for work) is where the gateway's
messages come in (rosgate_browser.pump).
"""

import json

import rosgate_browser as _browser
import rosgate_interfaces as _interfaces
from rclpy.logging import LoggingSeverity, _emit


class Engine:
    """The program's entities by name and op id; one per run."""

    def __init__(self):
        self.subscriptions = {}     # absolute topic -> [Subscription]
        self.publishers = {}        # absolute topic -> [Publisher]
        self.services = {}          # absolute service -> Service
        self.action_servers = {}    # absolute action -> ActionServer
        self.replies = {}           # op id -> handler(message) of a client's call or goal
        self.wakeups = 0            # bumped by every message for the program: an executor waiting looks again
        self.refusals = set()       # ops the gateway refused, said once each (_status)
        _browser.attach(self)

    # ---- out
    def next_id(self, op, name):
        return "%s:%s:%d" % (op, name, _browser.next_id())

    def send(self, message):
        _browser.send(json.dumps(message))

    # ---- in (rosgate_browser.pump hands every message of the program here)
    def on_message(self, m):
        op = m.get("op")
        if op == "publish":
            for sub in list(self.subscriptions.get(m.get("topic"), ())):
                sub._receive(m.get("msg"))
        elif op == "call_service":
            service = self.services.get(m.get("service"))
            if service is not None:
                service._receive(m)
        elif op in ("send_action_goal", "cancel_action_goal"):
            server = self.action_servers.get(m.get("action"))
            if server is not None:
                server._receive(m)
        elif op in ("service_response", "action_feedback", "action_result", "status"):
            handler = self.replies.get(m.get("id"))
            if handler is not None:
                handler(m)
            elif op == "status":
                self._status(m)
        else:
            return
        self.wakeups += 1

    def _status(self, m):
        """The gateway refused an op of the program (a publish the lease or the topic rules refuse,
        a service name it already has ...): said once per op and name, as a ROS error line (rclpy
        has no refusals: on a robot these would not happen)."""
        op_id = str(m.get("id") or "")
        if m.get("level") not in ("error", "warning") or not op_id:
            return   # (a status naming no op is about the page, not the program)
        key = op_id.rsplit(":", 1)[0] or m.get("msg")
        if key in self.refusals:
            return
        self.refusals.add(key)
        severity = LoggingSeverity.ERROR if m.get("level") == "error" else LoggingSeverity.WARN
        _emit(severity, "gateway", m.get("msg") or "refused %s" % op_id)

    # ---- types
    @staticmethod
    def type_name(cls):
        return _interfaces.type_name(cls)

    @staticmethod
    def to_json(msg):
        return _interfaces.to_json(msg)

    @staticmethod
    def from_json(cls, values):
        return _interfaces.from_json(cls, values)

    # ---- the graph, through rosapi
    @staticmethod
    def rosapi(name, args=None, timeout=60.0):
        return _browser.rosapi(name, args, timeout)


_engine = None


def engine():
    global _engine
    if _engine is None:
        _engine = Engine()
    return _engine


def pump(timeout):
    """Waits up to timeout s (None: until something comes) for the gateway's messages."""
    return _browser.pump(timeout)
