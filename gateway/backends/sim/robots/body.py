"""The rover's own description, published as a real robot's robot_state_publisher and wheel
driver publish theirs, under the same names: ``robot_description`` (std_msgs/msg/String,
transient local: a subscriber that comes later still gets it) and ``joint_states``
(sensor_msgs/msg/JointState: the two continuous wheel joints, turned by the distance each wheel
rolled). So the 3D twin draws the sim's rover as it draws any robot, from its URDF, placed by
TF and turning its wheels, and a page tried on the sim works on a real robot. The URDF has
primitives only (no meshes to serve); its links are the frames the rover's TF names
(``base_link``, ``base_scan``)."""

from __future__ import annotations

from ...base import QoS
from .msgs import has_subscribers, header

WHEEL_RADIUS = 0.07
WHEEL_Y = 0.165
JOINTS = ('left_wheel_joint', 'right_wheel_joint')


def _wheel(side: str, y: float) -> str:
    return f'''  <link name="{side}_wheel_link">
    <visual><origin rpy="1.5707963 0 0"/><geometry><cylinder radius="{WHEEL_RADIUS}" length="0.05"/></geometry>
      <material name="{side}_wheel"><color rgba="0.267 0.290 0.333 1"/></material></visual>
    <visual><origin xyz="0.04 0 0"/><geometry><box size="0.03 0.052 0.02"/></geometry>
      <material name="{side}_hub"><color rgba="0.8 0.8 0.8 1"/></material></visual>
  </link>
  <joint name="{side}_wheel_joint" type="continuous">
    <parent link="base_link"/><child link="{side}_wheel_link"/><origin xyz="0 {y} {WHEEL_RADIUS}"/><axis xyz="0 1 0"/>
  </joint>
'''


URDF = f'''<?xml version="1.0"?>
<robot name="rover">
  <link name="base_link">
    <visual name="body"><origin xyz="0 0 0.1"/><geometry><box size="0.4 0.26 0.12"/></geometry>
      <material name="body"><color rgba="0.941 0.549 0.102 1"/></material></visual>
    <visual name="nose"><origin xyz="0.2 0 0.12"/><geometry><box size="0.06 0.2 0.06"/></geometry>
      <material name="white"><color rgba="1 1 1 1"/></material></visual>
  </link>
  <link name="base_scan">
    <visual><origin xyz="0 0 0.02"/><geometry><cylinder radius="0.05" length="0.05"/></geometry>
      <material name="lidar"><color rgba="0.133 0.133 0.133 1"/></material></visual>
  </link>
  <joint name="base_scan_joint" type="fixed"><parent link="base_link"/><child link="base_scan"/><origin xyz="0 0 0.17"/></joint>
{_wheel('left', WHEEL_Y)}{_wheel('right', -WHEEL_Y)}</robot>
'''


class Body:
    """The rover's description (published once, retained) and its wheels' joint states."""

    def __init__(self, node, track: float):
        self.track = track
        self.angles = [0.0, 0.0]
        self.speeds = [0.0, 0.0]
        description = node.create_publisher('robot_description', 'std_msgs/msg/String',
                                            QoS(depth=1, transient_local=True))
        description.publish({'data': URDF})
        self.pub = node.create_publisher('joint_states', 'sensor_msgs/msg/JointState', QoS(depth=10))

    def roll(self, v: float, w: float, dt: float) -> None:
        """Each wheel turns by the distance it rolled (differential drive)."""
        self.speeds = [(v - w * self.track / 2) / WHEEL_RADIUS, (v + w * self.track / 2) / WHEEL_RADIUS]
        self.angles = [a + s * dt for a, s in zip(self.angles, self.speeds, strict=True)]

    def reset(self) -> None:
        self.angles, self.speeds = [0.0, 0.0], [0.0, 0.0]

    def publish(self, now: dict) -> None:
        if has_subscribers(self.pub):
            self.pub.publish({'header': header('', now), 'name': list(JOINTS), 'position': list(self.angles),
                              'velocity': list(self.speeds), 'effort': []})
