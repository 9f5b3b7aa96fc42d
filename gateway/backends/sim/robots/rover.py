"""A differential-drive rover with sensors, in a world of walls (see world.py).

Node ``rover``. In: ``cmd_vel`` (geometry_msgs/msg/Twist, or TwistStamped with the flag),
0.5 s command timeout, velocity and acceleration limits (node parameters). Out: ``odom``,
``tf`` (odom -> base_link), ``tf_static``, ``scan`` (360 beams), ``imu``, ``battery_state``,
``motor/left|right/temperature``, ``bumper`` (std_msgs/msg/Bool, true while touching a wall),
``camera/image_raw/compressed`` (JPEG, first-person), ``points`` (sensor_msgs/msg/PointCloud2 of a
16-ring 3D lidar: depth.py), ``robot_description`` and ``joint_states``
(its URDF and wheel joints, as a real robot: body.py). Service ``reset_world`` (std_srvs/srv/Empty).
Hitting a wall stops the rover (its commanded speed too; a new command is needed).
Costly outputs (scan, camera, odometry) are computed only while someone subscribes.
"""

from __future__ import annotations

import math

import numpy as np

from ...base import BackendError, QoS
from . import markers as mk
from .body import Body
from .camera import Camera
from .depth import DepthSensor
from .msgs import RosLog, has_subscribers, header, normalize_angle, stamp, transform, vector3, yaw_quaternion
from .world import World

STEP = 0.02                 # physics at 50 Hz
RADIUS = 0.18
TRACK = 0.3                 # wheel separation
TIMEOUT = 0.5
BEAMS = 360
RANGE_MIN, RANGE_MAX = 0.12, 12.0
CAPACITY = 2.0              # Ah
IDLE_CURRENT, DRIVE_CURRENT, TURN_CURRENT = 0.25, 2.5, 0.8
AMBIENT, HEAT_RISE, HEAT_TAU = 25.0, 35.0, 30.0
# steps between outputs: odom/tf/imu 25 Hz, markers 10 Hz, scan/camera 5 Hz, bumper 10 Hz, battery/temperature 1 Hz
EVERY = {'odom': 2, 'markers': 5, 'scan': 10, 'camera': 10, 'bumper': 5, 'slow': 50}
PARAMS = {'max_linear_velocity': 0.8, 'max_angular_velocity': 2.5,
          'max_linear_acceleration': 1.5, 'max_angular_acceleration': 6.0}
SCAN_ANGLES = np.arange(BEAMS) * (2 * math.pi / BEAMS)
SENSOR = QoS(depth=5, reliable=False)


class Rover:
    def __init__(self, graph, hub: mk.MarkerHub, world: World, namespace: str = '/', speed: float = 1.0,
                 twist_stamped: bool = False, name: str = 'rover'):
        self.node = node = graph.node(name, namespace)
        self.hub, self.world, self.speed, self.twist_stamped = hub, world, speed, twist_stamped
        self.log = RosLog(node, node.name.lstrip('/').replace('/', '.'))
        self.camera = Camera(world)
        self.depth = DepthSensor(world)
        self.limits = dict(PARAMS)
        for key, value in PARAMS.items():
            node.declare_parameter(key, value, on_set=lambda v, key=key: self.check_limit(key, v))
        node.declare_parameter('use_sim_time', False)
        cmd_type = 'geometry_msgs/msg/TwistStamped' if twist_stamped else 'geometry_msgs/msg/Twist'
        node.create_subscription('cmd_vel', cmd_type, self.on_cmd_vel, QoS(depth=10))
        node.create_service('reset_world', 'std_srvs/srv/Empty', self.on_reset_world)
        pub = node.create_publisher
        self.odom_pub = pub('odom', 'nav_msgs/msg/Odometry', QoS(depth=10))
        self.tf_pub = pub('tf', 'tf2_msgs/msg/TFMessage', QoS(depth=100))
        self.tf_static_pub = pub('tf_static', 'tf2_msgs/msg/TFMessage', QoS(depth=1, transient_local=True))
        self.scan_pub = pub('scan', 'sensor_msgs/msg/LaserScan', SENSOR)
        self.imu_pub = pub('imu', 'sensor_msgs/msg/Imu', SENSOR)
        self.battery_pub = pub('battery_state', 'sensor_msgs/msg/BatteryState', SENSOR)
        self.temp_pubs = [pub(f'motor/{side}/temperature', 'sensor_msgs/msg/Temperature', SENSOR)
                          for side in ('left', 'right')]
        self.bumper_pub = pub('bumper', 'std_msgs/msg/Bool', QoS(depth=10))
        self.camera_pub = pub('camera/image_raw/compressed', 'sensor_msgs/msg/CompressedImage', SENSOR)
        self.points_pub = pub('points', 'sensor_msgs/msg/PointCloud2', SENSOR)
        self.prefix = '' if namespace == '/' else namespace.strip('/') + '/'
        self.body = Body(node, TRACK)
        self.tf_static_pub.publish({'transforms': [
            transform('world', self.prefix + 'odom', *world.start[:2], 0.0, world.start[2]),
            transform(self.prefix + 'base_link', self.prefix + 'base_scan', 0.0, 0.0, 0.17, 0.0),
            transform(self.prefix + 'base_link', self.prefix + 'imu_link', 0.0, 0.0, 0.05, 0.0),
            transform(self.prefix + 'base_link', self.prefix + 'camera_link', 0.08, 0.0, 0.15, 0.0),
            transform(self.prefix + 'base_link', self.prefix + 'lidar_link', 0.0, 0.0, 0.25, 0.0)]})
        self.robot_id = hub.robot_id(node.name)
        hub.set_static(mk.outline(1, world.width, world.height))
        for i, b in enumerate(world.boxes, start=1):
            hub.set_static(mk.marker('walls', i, mk.CUBE, pose=mk.pose(b.x, b.y, b.yaw, z=world.wall_height / 2),
                                     scale=(b.sx, b.sy, world.wall_height), rgba=mk.color(*b.color)))
        self.time, self.steps = 0.0, 0
        self.reset()
        node.create_timer(STEP, self.tick)

    def destroy(self) -> None:
        self.node.destroy()

    def check_limit(self, key: str, value) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 100:
            self.node.params[key] = self.limits[key]
            raise BackendError(f'{key} must be a positive number (below 100)')
        self.limits[key] = float(value)

    def reset(self) -> None:
        self.x, self.y, self.yaw = self.world.start
        self.v = self.w = self.accel = 0.0
        self.cmd_v = self.cmd_w = 0.0
        self.last_cmd = -math.inf
        self.charge = CAPACITY
        self.current = IDLE_CURRENT
        self.temps = [AMBIENT, AMBIENT]
        self.bumper = self.bump_logged = False
        self.empty_logged = False
        self.last_marker_pose = None
        self.last_scan_pose = None   # the scan's marker is sent again only when the robot moved
        self.ranges = None
        self.body.reset()

    # --- inputs ---------------------------------------------------------------------------
    def on_cmd_vel(self, msg: dict) -> None:
        twist = msg['twist'] if self.twist_stamped else msg
        self.cmd_v, self.cmd_w = float(twist['linear']['x']), float(twist['angular']['z'])
        self.last_cmd = self.time

    def on_reset_world(self, req: dict) -> dict:
        self.log.info('Resetting the world')
        self.reset()
        self.publish_odom()
        self.publish_bumper()
        self.publish_slow()
        self.publish_markers()
        return {}

    # --- physics --------------------------------------------------------------------------
    def tick(self) -> None:
        dt = STEP * self.speed
        self.time += dt
        self.steps += 1
        self.step(dt)
        n = self.steps
        if n % EVERY['odom'] == 0:
            self.publish_odom()
        if n % EVERY['scan'] == 0:
            self.publish_scan()
        if n % EVERY['camera'] == 5 and has_subscribers(self.camera_pub):
            self.publish_camera()
        if n % EVERY['scan'] == 3 and has_subscribers(self.points_pub):
            self.points_pub.publish(self.depth.message(header(self.prefix + 'lidar_link'), self.x, self.y, self.yaw))
        if n % EVERY['bumper'] == 0:
            self.publish_bumper()
        if n % EVERY['markers'] == 0:
            self.publish_markers()
        if n % EVERY['slow'] == 0:
            self.publish_slow()

    def step(self, dt: float) -> None:
        p = self.node.params
        target_v, target_w = self.cmd_v, self.cmd_w
        if self.time - self.last_cmd > TIMEOUT or self.charge <= 0:
            target_v = target_w = 0.0
        vmax, wmax = p['max_linear_velocity'], p['max_angular_velocity']
        target_v = min(max(target_v, -vmax), vmax)
        target_w = min(max(target_w, -wmax), wmax)
        old_v = self.v
        self.v = _approach(self.v, target_v, p['max_linear_acceleration'] * dt)
        self.w = _approach(self.w, target_w, p['max_angular_acceleration'] * dt)

        yaw = self.yaw + self.w * dt
        mid = self.yaw + self.w * dt / 2
        nx, ny = self.x + self.v * dt * math.cos(mid), self.y + self.v * dt * math.sin(mid)
        stalled = False
        if self.v:
            before, after = self.world.clearance(self.x, self.y), self.world.clearance(nx, ny)
            if after < RADIUS and after < before:
                frac = self.free_fraction(nx, ny)
                nx, ny = self.x + frac * (nx - self.x), self.y + frac * (ny - self.y)
                stalled = True
                if not self.bump_logged:  # once per contact
                    self.bump_logged = True
                    self.log.warn(f'Bumped into a wall at x={nx:.2f}, y={ny:.2f}: stopping')
                self.v = self.cmd_v = 0.0
        self.x, self.y, self.yaw = nx, ny, normalize_angle(yaw)
        self.body.roll(self.v, self.w, dt)
        self.accel = (self.v - old_v) / dt if dt else 0.0
        bumper = self.world.clearance(self.x, self.y) < RADIUS + 0.01
        if bumper != self.bumper:
            self.bumper = bumper
            self.bump_logged = self.bump_logged and bumper
            self.publish_bumper()
        self.heat_and_drain(dt, stalled)

    def free_fraction(self, nx: float, ny: float) -> float:
        """How far along a move the rover gets before touching a wall (bisection)."""
        lo, hi = 0.0, 1.0
        for _ in range(8):
            mid = (lo + hi) / 2
            if self.world.clearance(self.x + mid * (nx - self.x), self.y + mid * (ny - self.y)) >= RADIUS:
                lo = mid
            else:
                hi = mid
        return lo

    def heat_and_drain(self, dt: float, stalled: bool) -> None:
        p = self.node.params
        vmax, wmax = p['max_linear_velocity'], p['max_angular_velocity']
        effort = abs(self.accel) / max(p['max_linear_acceleration'], 1e-6)
        self.current = (IDLE_CURRENT + DRIVE_CURRENT * (abs(self.v) / vmax + 0.5 * effort + stalled)
                        + TURN_CURRENT * abs(self.w) / wmax)
        self.charge = max(0.0, self.charge - self.current * dt / 3600)
        if self.charge <= 0 and not self.empty_logged:
            self.empty_logged = True
            self.log.error('Battery empty: motors disabled until /reset_world')
        for i, wheel in enumerate((self.v - self.w * TRACK / 2, self.v + self.w * TRACK / 2)):
            load = min(1.0, abs(wheel) / vmax + 0.3 * effort + stalled)
            target = AMBIENT + HEAT_RISE * load * load
            self.temps[i] += (target - self.temps[i]) * (1 - math.exp(-dt / HEAT_TAU))

    # --- outputs --------------------------------------------------------------------------
    def odom_pose(self) -> tuple[float, float, float]:
        sx, sy, syaw = self.world.start
        dx, dy = self.x - sx, self.y - sy
        c, s = math.cos(syaw), math.sin(syaw)
        return c * dx + s * dy, -s * dx + c * dy, normalize_angle(self.yaw - syaw)

    def publish_odom(self) -> None:
        now = stamp()
        x, y, yaw = self.odom_pose()
        if has_subscribers(self.odom_pub):
            cov = [0.0] * 36
            for i in range(6):
                cov[i * 7] = 1e-3
            self.odom_pub.publish({
                'header': header(self.prefix + 'odom', now), 'child_frame_id': self.prefix + 'base_link',
                'pose': {'pose': {'position': vector3(x, y), 'orientation': yaw_quaternion(yaw)},
                         'covariance': cov},
                'twist': {'twist': {'linear': vector3(self.v), 'angular': vector3(z=self.w)},
                          'covariance': cov}})
        if has_subscribers(self.tf_pub):
            self.tf_pub.publish({'transforms': [
                transform(self.prefix + 'odom', self.prefix + 'base_link', x, y, 0.0, yaw, now)]})
        self.body.publish(now)
        if has_subscribers(self.imu_pub):
            self.imu_pub.publish({
                'header': header(self.prefix + 'imu_link', now), 'orientation': yaw_quaternion(yaw),
                'orientation_covariance': [1e-4, 0, 0, 0, 1e-4, 0, 0, 0, 1e-4],
                'angular_velocity': vector3(z=self.w),
                'angular_velocity_covariance': [1e-5, 0, 0, 0, 1e-5, 0, 0, 0, 1e-5],
                'linear_acceleration': vector3(self.accel, self.v * self.w, 9.80665),
                'linear_acceleration_covariance': [1e-3, 0, 0, 0, 1e-3, 0, 0, 0, 1e-3]})

    def cast_scan(self) -> np.ndarray:
        ranges, _ = self.world.cast(self.x, self.y, SCAN_ANGLES + self.yaw)
        ranges[ranges > RANGE_MAX] = np.inf
        self.ranges = ranges
        return ranges

    def publish_scan(self) -> None:
        if not has_subscribers(self.scan_pub):
            return
        ranges = self.cast_scan()
        self.scan_pub.publish({
            'header': header(self.prefix + 'base_scan'), 'angle_min': 0.0,
            'angle_max': float(SCAN_ANGLES[-1]), 'angle_increment': 2 * math.pi / BEAMS,
            'time_increment': 0.2 / BEAMS, 'scan_time': 0.2, 'range_min': RANGE_MIN,
            'range_max': RANGE_MAX, 'ranges': ranges.tolist(), 'intensities': []})

    def publish_camera(self) -> None:
        data = self.camera.jpeg(self.x + 0.08 * math.cos(self.yaw), self.y + 0.08 * math.sin(self.yaw), self.yaw)
        self.camera_pub.publish({'header': header(self.prefix + 'camera_link'),
                                 'format': 'rgb8; jpeg compressed bgr8', 'data': data})

    def publish_bumper(self) -> None:
        self.bumper_pub.publish({'data': self.bumper})

    def publish_slow(self) -> None:
        now = stamp()
        pct = self.charge / CAPACITY
        if has_subscribers(self.battery_pub):
            self.battery_pub.publish({
                'header': header(self.prefix + 'base_link', now),
                'voltage': 10.5 + 2.1 * pct - 0.05 * self.current, 'temperature': 25.0,
                'current': -self.current, 'charge': self.charge, 'capacity': CAPACITY,
                'design_capacity': CAPACITY, 'percentage': pct,
                'power_supply_status': 2 if pct > 0 else 3,   # DISCHARGING / NOT_CHARGING
                'power_supply_health': 1 if pct > 0 else 3,   # GOOD / DEAD
                'power_supply_technology': 3,                 # LIPO
                'present': True, 'cell_voltage': [], 'cell_temperature': [],
                'location': 'base', 'serial_number': ''})
        for pub, temp, side in zip(self.temp_pubs, self.temps, ('left', 'right'), strict=True):
            if has_subscribers(pub):
                pub.publish({'header': header(f'{self.prefix}{side}_motor', now),
                             'temperature': temp, 'variance': 0.01})

    def publish_markers(self) -> None:
        pose = (self.x, self.y, self.yaw)
        if pose != self.last_marker_pose:
            self.last_marker_pose = pose
            self.hub.update(mk.marker('robots', self.robot_id, mk.ARROW, pose=mk.pose(*pose),
                                      scale=(0.45, 0.3, 0.2), rgba=mk.color(0.95, 0.55, 0.1),
                                      text=self.node.name.rsplit('/', 1)[-1]))
        if self.steps % EVERY['scan'] == 0 and pose != self.last_scan_pose and has_subscribers(self.hub.pub):
            self.last_scan_pose = pose   # the walls do not move: a still robot's scan is the same
            ranges = self.ranges if self.ranges is not None and has_subscribers(self.scan_pub) else self.cast_scan()
            hit = np.isfinite(ranges)
            angles = SCAN_ANGLES[hit] + self.yaw
            xs, ys = self.x + ranges[hit] * np.cos(angles), self.y + ranges[hit] * np.sin(angles)
            self.hub.update(mk.marker('scan', self.robot_id, mk.POINTS, scale=(0.05, 0.05, 0),
                                      rgba=mk.color(0.9, 0.1, 0.1),
                                      points=[mk.point(px, py) for px, py in zip(xs.tolist(), ys.tolist())]))
        self.hub.flush()


def _approach(value: float, target: float, step: float) -> float:
    if value < target:
        return min(value + step, target)
    return max(value - step, target)

