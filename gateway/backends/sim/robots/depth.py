"""A 3D lidar on the rover: 16 rings of 360 beams, as sensor_msgs/PointCloud2 (``points``).

Each beam leaves the sensor (``lidar_link``, 0.25 m above the floor) at its azimuth and elevation
(-15 deg to +15 deg, as a VLP-16); a beam pointing down meets the floor where that comes before the
wall its azimuth's ray reaches (world.cast), any other meets the wall if it is tall enough there,
else it returns nothing (no point). Points are x, y, z, intensity (float32 each, 16 bytes, little
endian): 5,760 beams, some 90 KB a cloud at 5 Hz. What a page can draw of that is the gateway's
to decide (bridge/clouds.py thins it to the ``points`` a subscriber asks for).
"""

from __future__ import annotations

import math

import numpy as np

from .world import World

AZIMUTHS = 360
RINGS = np.radians(np.linspace(-15.0, 15.0, 16))
HEIGHT = 0.25            # m above the floor
RANGE_MAX = 12.0
FLOAT32 = 7              # sensor_msgs/PointField.FLOAT32
FIELDS = [{'name': n, 'offset': 4 * i, 'datatype': FLOAT32, 'count': 1}
          for i, n in enumerate(('x', 'y', 'z', 'intensity'))]


class DepthSensor:
    def __init__(self, world: World):
        self.world = world
        self.azimuths = np.arange(AZIMUTHS) * (2 * math.pi / AZIMUTHS)
        self._last: tuple[tuple[float, float, float], np.ndarray] | None = None   # pose -> its points

    def points(self, x: float, y: float, yaw: float) -> np.ndarray:
        """(n, 4) float32 x, y, z, intensity in the sensor's frame, from a sensor at (x, y, yaw)."""
        if self._last is not None and self._last[0] == (x, y, yaw):
            return self._last[1]   # the walls do not move: a still rover sees the same cloud
        wall, _ = self.world.cast(x, y, self.azimuths + yaw)               # (azimuths,)
        tan = np.tan(RINGS)[:, None]                                       # (rings, 1)
        floor = np.where(tan < 0, HEIGHT / np.maximum(-tan, 1e-9), np.inf)   # horizontal distance to the floor
        distance = np.minimum(np.broadcast_to(wall, (len(RINGS), AZIMUTHS)), floor)
        z = HEIGHT + distance * tan
        hit = np.isfinite(distance) & (distance <= RANGE_MAX) & (z <= self.world.wall_height) & (z >= -1e-6)
        rings, beams = np.nonzero(hit)
        d = distance[rings, beams]
        a = self.azimuths[beams]
        cloud = np.empty((len(d), 4), np.float32)
        cloud[:, 0] = d * np.cos(a)
        cloud[:, 1] = d * np.sin(a)
        cloud[:, 2] = z[rings, beams] - HEIGHT
        cloud[:, 3] = np.clip(100.0 / (1.0 + d), 0, 100)                  # nearer: brighter
        self._last = ((x, y, yaw), cloud)
        return cloud

    def message(self, header: dict, x: float, y: float, yaw: float) -> dict:
        cloud = self.points(x, y, yaw)
        return {'header': header, 'height': 1, 'width': len(cloud), 'fields': FIELDS, 'is_bigendian': False,
                'point_step': 16, 'row_step': 16 * len(cloud), 'data': cloud.astype('<f4').tobytes(),
                'is_dense': True}
