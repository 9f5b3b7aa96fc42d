"""A ROS 2 node as a run: an rclpy program (the IDE's "ROS 2 node" of a block program, or a Python
program that imports rclpy) started as a node of the ROS graph.

The node the IDE generates (``ide/generators/node.js``) is plain rclpy with no runtime of ours, so the
run's ``program.py`` is the source as it is; its robot namespace comes as ``ros2 run`` passes it
(``--ros-args -r __ns:=NS``). Only a trusted run (``--trusted-runs``: on the ROS graph, with the
gateway's ROS installs) can be a node.
"""

from __future__ import annotations

import re

KIND = 'ros2_node'
RCLPY_IMPORT = re.compile(r'^\s*(import\s+rclpy\b|from\s+rclpy(\.\w+)*\s+import\s)', re.M)


def node_program(source: str) -> str:
    """program.py for a run of the node ``source``; ValueError when it is not an rclpy program."""
    if not RCLPY_IMPORT.search(source):
        raise ValueError('a ROS 2 node run takes an rclpy program (a node: it imports rclpy), '
                         'such as the IDE\'s "ROS 2 node" of a block program')
    return source


def node_arguments(ns: str) -> list[str]:
    """The node's arguments for a run in namespace ns (as ``ros2 run ... --ros-args -r __ns:=NS``)."""
    return ['--ros-args', '-r', f'__ns:={ns}'] if ns else []
