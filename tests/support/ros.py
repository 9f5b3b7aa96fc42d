"""roslibpy clients of a gateway: a connection, the messages of a topic with their arrival times,
service calls, and a Twist published at a rate. roslibpy is imported where it is used: the rclpy
environment (make test-rclpy) loads this plugin without it."""

from __future__ import annotations

import threading
import time
from contextlib import contextmanager

from tests.support.wait import TIMEOUT, wait_for


@contextmanager
def client(gw, token: str | None = None):
    """A roslibpy connection to a gateway (signed in with ``token`` if given), closed on leaving."""
    import roslibpy
    ros = roslibpy.Ros(f'ws://{gw.host}:{gw.port}/?token={token}') if token else roslibpy.Ros(gw.host, gw.port)
    ros.run(timeout=TIMEOUT)
    try:
        yield ros
    finally:
        ros.close()


class Watch:
    """Records every message of a topic with its arrival time (an independent roslibpy client)."""

    def __init__(self, ros, topic: str, type_: str):
        import roslibpy
        self.messages: list[tuple[float, dict]] = []
        self.lock = threading.Lock()
        self.topic = roslibpy.Topic(ros, topic, type_)
        self.topic.subscribe(self._on)

    def _on(self, msg):
        with self.lock:
            self.messages.append((time.monotonic(), dict(msg)))

    def latest(self):
        with self.lock:
            return self.messages[-1][1] if self.messages else None

    def since(self, t0: float) -> list[tuple[float, dict]]:
        with self.lock:
            return [(t, m) for t, m in self.messages if t >= t0]

    def close(self):
        self.topic.unsubscribe()


class RosClient:
    """A roslibpy connection with helpers used to check robots independently of the browser."""

    def __init__(self, gateway):
        import roslibpy
        self.roslibpy = roslibpy
        self.ros = roslibpy.Ros(gateway.host, gateway.port)
        self.ros.run(timeout=TIMEOUT)
        self.watches: list[Watch] = []

    def watch(self, topic: str, type_: str) -> Watch:
        w = Watch(self.ros, topic, type_)
        self.watches.append(w)
        return w

    def call(self, service: str, type_: str, args: dict | None = None, timeout: float = TIMEOUT):
        srv = self.roslibpy.Service(self.ros, service, type_)
        return srv.call(self.roslibpy.ServiceRequest(args or {}), timeout=timeout)

    def __enter__(self) -> RosClient:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self):
        for w in self.watches:
            try:
                w.close()
            except Exception:
                pass
        self.ros.close()


class Inbox:
    """Messages of one topic with their arrival times (monotonic); as a context, unsubscribed on
    leaving it."""

    def __init__(self, ros, topic: str, type: str, **kwargs):
        import roslibpy
        self.items: list[tuple[float, dict]] = []
        self.lock = threading.Lock()
        self.topic = roslibpy.Topic(ros, topic, type, **kwargs)
        self.topic.subscribe(self._add)

    def _add(self, msg: dict) -> None:
        with self.lock:
            self.items.append((time.monotonic(), msg))

    @property
    def messages(self) -> list[dict]:
        with self.lock:
            return [m for _, m in self.items]

    @property
    def last(self) -> dict | None:
        with self.lock:
            return self.items[-1][1] if self.items else None

    def since(self, t: float) -> list[dict]:
        with self.lock:
            return [m for at, m in self.items if at >= t]

    def wait(self, predicate=lambda m: True, timeout: float = TIMEOUT, after: float = 0.0) -> dict:
        """The first message (arrived after ``after``) that satisfies predicate."""
        def found():
            return next((m for m in self.since(after) if predicate(m)), None)
        return wait_for(found, timeout)

    def close(self) -> None:
        self.topic.unsubscribe()

    def __enter__(self) -> Inbox:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def call(ros, name: str, type: str, request: dict | None = None, timeout: float = TIMEOUT) -> dict:
    import roslibpy
    return roslibpy.Service(ros, name, type).call(roslibpy.ServiceRequest(request or {}), timeout=timeout)


def twist(x: float = 0.0, z: float = 0.0) -> dict:
    return {'linear': {'x': x, 'y': 0.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': z}}


def stream(pub, msg: dict, seconds: float, rate: float = 20.0) -> float:
    """Publish msg at rate for seconds; the time of the last publish."""
    import roslibpy
    start = time.monotonic()
    last = start
    while time.monotonic() - start < seconds:
        pub.publish(roslibpy.Message(msg))
        last = time.monotonic()
        time.sleep(1 / rate)
    return last


def cancelled(action, goal: dict, after_feedback: int, timeout: float) -> dict:
    """Sends ``goal`` with a roslibpy ActionClient and cancels it after ``after_feedback`` feedbacks;
    its result, which says CANCELED."""
    import roslibpy
    results, feedback = [], []
    goal_id = action.send_goal(roslibpy.Goal(goal), results.append, feedback.append, results.append)
    wait_for(lambda: len(feedback) >= after_feedback)
    action.cancel_goal(goal_id)
    action.wait_goal(goal_id, timeout=timeout)
    assert results[0]['status'] == roslibpy.GoalStatus.CANCELED, results[0]
    return results[0]


START = 5.544445   # where turtlesim puts turtle1, and puts it back on /reset
# A program's move and turn (ide/runtime) stop on the pose they last saw: the last command (at
# least 0.1 m/s or 0.1 rad/s) runs on for the round trip to the page, which a loaded 2-core
# machine stretches to most of a second; above the floor the proportional approach (GAIN 6/s)
# runs on for that round trip too (measured: 0.21 m past a 2.5 m move's end at load 5-8, with
# Pyodide starting in the other test process). What one closed-loop move or turn may be off by:
LOOP_REACH = 0.25                  # m
LOOP_HEADING = 0.1                 # rad (6 degrees)


def reset_turtlesim(ros):
    """/reset, then until turtle1 is back at its start; returns the pose watch."""
    ros.call("/reset", "std_srvs/srv/Empty")
    pose = ros.watch("/turtle1/pose", "turtlesim/msg/Pose")
    wait_for(lambda: (p := pose.latest()) and abs(p["x"] - START) < 1e-3 and abs(p["y"] - START) < 1e-3
             and abs(p["theta"]) < 1e-3, what="turtle1 back at the start after /reset")
    return pose
