"""A robot for the graph types tests: a ROS node whose interface packages (rosgate_robot_msgs,
turtlesim, tf2_msgs) exist only in its own prefixes, which the gateway does not have.

Run as ``python graph_robot.py`` with ``build.env_with(prefixes)``. Publishes ``/robot/status``
(rosgate_robot_msgs/msg/Status), ``/turtle1/pose`` (turtlesim/msg/Pose) and ``/tf``
(tf2_msgs/msg/TFMessage) ten times a second; prints each ``/robot/cmd_wheel`` it hears as
``wheel {json}`` and each ``/robot/status_in`` (Status) as ``status {json}``; serves ``/robot/configure`` (rosgate_robot_msgs/srv/Configure) and ``/spawn``
(turtlesim/srv/Spawn), and the action ``/turtle1/rotate_absolute`` (turtlesim/action/RotateAbsolute:
three feedbacks, then the result). Prints ``ready`` once up; stops on SIGTERM.
"""

from __future__ import annotations

import json
import signal
import time

import rclpy
from geometry_msgs.msg import TransformStamped
from rclpy.action import ActionServer
from rclpy.node import Node
from rosgate_robot_msgs.msg import Status, Wheel
from rosgate_robot_msgs.srv import Configure
from tf2_msgs.msg import TFMessage
from turtlesim.action import RotateAbsolute
from turtlesim.msg import Pose
from turtlesim.srv import Spawn


FEEDBACK = '/turtle1/rotate_absolute/_action/feedback'


def say(*parts) -> None:
    print(*parts, flush=True)


def status(count: int) -> Status:
    s = Status()
    s.header.frame_id = 'base'
    s.header.stamp.sec = 7
    s.mode = Status.MODE_DRIVE
    s.wheels[0].side, s.wheels[0].speed = Wheel.LEFT, 0.5
    s.wheels[1].side, s.wheels[1].speed, s.wheels[1].label = Wheel.RIGHT, -0.5, 'right'
    s.spare = [Wheel(side=Wheel.RIGHT, speed=2.0, label='spare')]
    s.readings = [1.5, 2.5]
    s.blob = b'\x01\x02\x03'
    s.short_name = 'r2'
    s.small = [1, -2]
    s.pose.position.x = 1.25
    s.count = count
    return s


class Robot(Node):
    def __init__(self):
        super().__init__('robot')
        self.count = 0
        self.status = self.create_publisher(Status, '/robot/status', 10)
        self.pose = self.create_publisher(Pose, '/turtle1/pose', 10)
        self.tf = self.create_publisher(TFMessage, '/tf', 10)
        self.create_subscription(Wheel, '/robot/cmd_wheel', self.on_wheel, 10)
        self.create_subscription(Status, '/robot/status_in', self.on_status, 10)
        self.create_service(Configure, '/robot/configure', self.on_configure)
        self.create_service(Spawn, '/spawn', self.on_spawn)
        self.rotate = ActionServer(self, RotateAbsolute, '/turtle1/rotate_absolute', self.on_rotate)
        self.create_timer(0.1, self.tick)

    def tick(self) -> None:
        self.count += 1
        self.status.publish(status(self.count))
        self.pose.publish(Pose(x=5.5, y=4.5, theta=0.25, linear_velocity=1.0, angular_velocity=0.0))
        t = TransformStamped()
        t.header.frame_id, t.child_frame_id = 'odom', 'base_link'
        t.transform.translation.x = 0.5
        t.transform.rotation.w = 1.0
        self.tf.publish(TFMessage(transforms=[t]))

    def on_wheel(self, msg: Wheel) -> None:
        say('wheel', json.dumps({'side': msg.side, 'speed': msg.speed, 'label': msg.label}))

    def on_status(self, msg: Status) -> None:
        say('status', json.dumps({
            'frame_id': msg.header.frame_id, 'mode': msg.mode,
            'wheels': [[w.side, w.speed, w.label] for w in msg.wheels],
            'spare': [[w.side, w.speed, w.label] for w in msg.spare], 'readings': list(msg.readings),
            'blob': list(msg.blob), 'short_name': msg.short_name, 'small': list(msg.small), 'ok': msg.ok,
            'x': msg.pose.position.x, 'w': msg.pose.orientation.w, 'count': msg.count}))

    def on_configure(self, request, response):
        response.success = True
        response.message = (f'configured {request.name} gains={list(request.gains)} '
                            f'speed={request.wheel.speed} label={request.wheel.label}')
        response.status = status(0)
        response.status.short_name = request.name[:16]
        return response

    def on_spawn(self, request, response):
        response.name = request.name or 'turtle2'
        return response

    def on_rotate(self, goal):
        theta = goal.request.theta
        # the caller's feedback subscription may not be matched yet when its first goal arrives
        # (DDS discovery): wait for it, as a caller that asked for feedback expects all of it
        deadline = time.monotonic() + 10
        while self.count_subscribers(FEEDBACK) == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
        for remaining in (theta * 2 / 3, theta / 3, 0.0):
            goal.publish_feedback(RotateAbsolute.Feedback(remaining=remaining))
            time.sleep(0.05)
        goal.succeed()
        return RotateAbsolute.Result(delta=-theta)


def main() -> None:
    rclpy.init()
    node = Robot()
    signal.signal(signal.SIGTERM, lambda *_: rclpy.try_shutdown())
    say('ready')
    try:
        rclpy.spin(node)
    except Exception:  # noqa: BLE001 (shut down by the signal)
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
