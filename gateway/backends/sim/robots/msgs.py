"""Message builders shared by the simulated robots (complete dicts in rosbridge shape)."""

from __future__ import annotations

import logging
import math
import time
from typing import Any

from ...base import QoS

Message = dict[str, Any]
IDENTITY_Q = {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}
LOG_LEVELS = {logging.DEBUG: 10, logging.INFO: 20, logging.WARNING: 30, logging.ERROR: 40}


def stamp() -> Message:
    ns = time.time_ns()
    return {'sec': ns // 1_000_000_000, 'nanosec': ns % 1_000_000_000}


def header(frame_id: str, at: Message | None = None) -> Message:
    return {'stamp': at or stamp(), 'frame_id': frame_id}


def yaw_quaternion(yaw: float) -> Message:
    return {'x': 0.0, 'y': 0.0, 'z': math.sin(yaw / 2), 'w': math.cos(yaw / 2)}


def vector3(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Message:
    return {'x': x, 'y': y, 'z': z}


def transform(parent: str, child: str, x: float, y: float, z: float, yaw: float,
              at: Message | None = None) -> Message:
    return {'header': header(parent, at), 'child_frame_id': child,
            'transform': {'translation': vector3(x, y, z), 'rotation': yaw_quaternion(yaw)}}


def normalize_angle(a: float) -> float:
    """Into [-pi, pi), as turtlesim's normalizeAngle."""
    return a - 2 * math.pi * math.floor((a + math.pi) / (2 * math.pi))


def has_subscribers(pub) -> bool:
    """Whether anything listens to a publisher's topic (so costly messages can be skipped)."""
    return pub.subscription_count > 0


def set_latched(pub, msg) -> None:
    """Replace what late subscribers of a transient-local publisher receive, without sending it now
    (a message, or a callable that builds it when a subscriber joins)."""
    pub.retain(msg)


ROSOUT = QoS(depth=1000, reliable=True, transient_local=True, lifespan=10.0)   # rcl's rosout profile


class RosLog:
    """A node's logger: Python logging plus rcl_interfaces/msg/Log on /rosout, as a ROS node logs
    (with rcl's QoS for it: a subscriber that joins gets the lines of the last 10 seconds)."""

    def __init__(self, node, name: str):
        self.name = name  # the logger name ROS would use: the node name without leading '/'
        self.log = logging.getLogger('rosgate.sim.' + name.replace('/', '.'))
        self.pub = node.create_publisher('/rosout', 'rcl_interfaces/msg/Log', ROSOUT)

    def __call__(self, level: int, text: str, function: str = '') -> None:
        self.log.log(level, '[%s]: %s', self.name, text)
        self.pub.publish({'stamp': stamp(), 'level': LOG_LEVELS[level], 'name': self.name,
                          'msg': text, 'file': '', 'function': function, 'line': 0})

    def info(self, text: str, function: str = '') -> None:
        self(logging.INFO, text, function)

    def warn(self, text: str, function: str = '') -> None:
        self(logging.WARNING, text, function)

    def error(self, text: str, function: str = '') -> None:
        self(logging.ERROR, text, function)
