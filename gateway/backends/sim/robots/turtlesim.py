"""A work-alike of ROS 2 Jazzy turtlesim_node: same names, types and behaviour.

Node ``turtlesim`` (in the station's namespace). Services ``spawn``, ``kill``, ``clear``,
``reset``; per turtle ``<name>/cmd_vel`` (in), ``<name>/pose``, ``<name>/color_sensor``,
``<name>/set_pen``, ``<name>/teleport_absolute``, ``<name>/teleport_relative`` and the action
``<name>/rotate_absolute``. Parameters ``background_r/g/b`` and ``holonomic`` (linear.y is
honoured only when true). A QTimer-like 16 ms tick integrates every turtle with dt = 0.016 s, as
the real node does. The pen draws into a transparent 500x500 raster (45 px per metre) that the
colour sensor reads (unpainted pixels read as white, as in the real node), and into pen markers
for the world view: live viewers get the segments drawn (a batch per turtle ~10 times a second),
a viewer joining late gets the raster (``markers.raster_boxes``), so the trails of a lesson of any
length take the raster's memory and no more.
"""

from __future__ import annotations

import math
import re

from PIL import Image, ImageDraw

from ...base import STATUS_ABORTED, STATUS_CANCELED, STATUS_SUCCEEDED, ActionServerCallbacks, BackendError, QoS
from . import markers as mk
from .msgs import RosLog, has_subscribers, normalize_angle

PIXELS = 500
METER = 45                                   # pixels per metre (the turtle image height)
SIZE = (PIXELS - 1) / METER                  # 11.0889 m
TICK = 0.016
CMD_TIMEOUT = 1.0
DEFAULT_BG = (69, 86, 255)
DEFAULT_PEN = (179, 184, 255, 3)
MARKER_EVERY = 6                             # ticks between world-view updates (~10 Hz)
TURTLE_COLORS = [(0.29, 0.66, 0.31), (0.95, 0.61, 0.07), (0.85, 0.27, 0.27), (0.55, 0.36, 0.76),
                 (0.1, 0.7, 0.75), (0.9, 0.45, 0.7)]
NAME = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$')
QOS = QoS(depth=7)
MAX_SPEED = 1000.0                           # m/s and rad/s: far past any real command, keeps the sums finite


def speed(value) -> float:
    """A commanded velocity as a finite float: NaN reads as 0 and infinities are capped."""
    v = float(value)
    return 0.0 if v != v else max(-MAX_SPEED, min(MAX_SPEED, v))


def finite(*values) -> bool:
    return all(math.isfinite(float(v)) for v in values)


class Turtle:
    def __init__(self, sim: Turtlesim, name: str, x: float, y: float, theta: float, index: int):
        self.sim, self.name, self.index = sim, name, index
        self.x, self.y, self.theta = x, y, theta
        self.lin_x = self.lin_y = self.ang = 0.0
        self.pen_on, self.pen = True, DEFAULT_PEN
        self.last_command = sim.time
        self.teleports: list[tuple[bool, float, float, float]] = []
        self.goal = self.goal_start = None
        self.goal_delta = 0.0
        self.pen_points: list[tuple[float, float]] = []   # segment pairs not yet in a marker
        self.pen_batch: list[dict] = []                   # markers not yet handed to the hub
        self.last_marker_pose = None
        self.last_warn = -math.inf
        node = sim.node
        self.handles = [
            node.create_subscription(f'{name}/cmd_vel', 'geometry_msgs/msg/Twist', self.on_cmd_vel, QOS),
            node.create_service(f'{name}/set_pen', 'turtlesim/srv/SetPen', self.on_set_pen),
            node.create_service(f'{name}/teleport_absolute', 'turtlesim/srv/TeleportAbsolute',
                                self.on_teleport_absolute),
            node.create_service(f'{name}/teleport_relative', 'turtlesim/srv/TeleportRelative',
                                self.on_teleport_relative),
            node.create_action_server(f'{name}/rotate_absolute', 'turtlesim/action/RotateAbsolute',
                                      ActionServerCallbacks(self.on_goal, lambda goal: None)),
        ]
        self.pose_pub = node.create_publisher(f'{name}/pose', 'turtlesim/msg/Pose', QOS)
        self.color_pub = node.create_publisher(f'{name}/color_sensor', 'turtlesim/msg/Color', QOS)
        self.handles += [self.pose_pub, self.color_pub]

    def destroy(self) -> None:
        for h in self.handles:
            h.destroy()
        self.handles = []

    # --- callbacks ------------------------------------------------------------------------
    def on_cmd_vel(self, msg: dict) -> None:
        self.last_command = self.sim.time
        self.lin_x = speed(msg['linear']['x'])
        self.lin_y = speed(msg['linear']['y']) if self.sim.node.params.get('holonomic') is True else 0.0
        self.ang = speed(msg['angular']['z'])
        if self.goal is not None:
            self.sim.log.warn('Velocity command received during rotation goal. Aborting goal')
            self.goal.finish(STATUS_ABORTED, {'delta': self.goal_delta})
            self.goal = None

    def on_set_pen(self, req: dict) -> dict:
        self.pen_marker()  # segments drawn so far keep the old pen
        self.pen_on = not req.get('off', 0)
        if req.get('off', 0):
            return {}
        width = req.get('width', 0) or 1  # a QPen built from a colour alone is 1 px wide
        self.pen = (req.get('r', 0), req.get('g', 0), req.get('b', 0), width)
        return {}

    def on_teleport_absolute(self, req: dict) -> dict:
        x, y, theta = req.get('x', 0.0), req.get('y', 0.0), req.get('theta', 0.0)
        if not finite(x, y, theta):
            raise BackendError('teleport_absolute: x, y and theta must be finite numbers')
        self.teleports.append((False, min(max(float(x), 0.0), SIZE), min(max(float(y), 0.0), SIZE),
                               float(theta)))
        return {}

    def on_teleport_relative(self, req: dict) -> dict:
        linear, angular = req.get('linear', 0.0), req.get('angular', 0.0)
        if not finite(linear, angular):
            raise BackendError('teleport_relative: linear and angular must be finite numbers')
        self.teleports.append((True, max(-2 * SIZE, min(2 * SIZE, float(linear))), 0.0, float(angular)))
        return {}

    def on_goal(self, goal) -> None:
        if self.goal is not None:
            self.sim.log.warn('Rotation goal received before a previous goal finished. Aborting previous goal')
            self.goal.finish(STATUS_ABORTED, {'delta': self.goal_delta})
        self.goal, self.goal_start, self.goal_delta = goal, self.theta, 0.0

    # --- the tick -------------------------------------------------------------------------
    def update(self, dt: float) -> None:
        for relative, a, b, theta in self.teleports:
            old = (self.x, self.y)
            if relative:
                self.theta += theta
                self.x += math.cos(self.theta) * a
                self.y += math.sin(self.theta) * a
            else:
                self.x, self.y, self.theta = a, min(b, SIZE), theta
            self.draw(old)
        self.teleports.clear()

        goal = self.goal
        if goal is not None and not goal.active:
            self.goal = goal = None
        if goal is not None:
            if goal.cancel_requested:
                self.sim.log.info('Rotation goal canceled')
                goal.finish(STATUS_CANCELED, {'delta': self.goal_delta})
                self.goal = None
                self.lin_x = self.lin_y = self.ang = 0.0
            else:
                target = normalize_angle(float(goal.request.get('theta', 0.0)))
                remaining = normalize_angle(target - self.theta)
                self.goal_delta = normalize_angle(self.goal_start - self.theta)
                goal.publish_feedback({'remaining': remaining})
                if abs(normalize_angle(self.theta - target)) < 0.02:
                    self.sim.log.info('Rotation goal completed successfully')
                    goal.finish(STATUS_SUCCEEDED, {'delta': self.goal_delta})
                    self.goal = None
                    self.lin_x = self.lin_y = self.ang = 0.0
                else:
                    self.lin_x = self.lin_y = 0.0
                    self.ang = -1.0 if remaining < 0.0 else 1.0
                    self.last_command = self.sim.time

        if self.sim.time - self.last_command > CMD_TIMEOUT:
            self.lin_x = self.lin_y = self.ang = 0.0

        old = (self.x, self.y)
        self.theta = normalize_angle(self.theta + self.ang * dt)
        c, s = math.cos(self.theta), math.sin(self.theta)
        self.x += c * self.lin_x * dt - s * self.lin_y * dt
        self.y += s * self.lin_x * dt + c * self.lin_y * dt
        if not (0 <= self.x <= SIZE and 0 <= self.y <= SIZE):
            if self.sim.time - self.last_warn >= 1.0:  # the real node warns on every tick
                self.last_warn = self.sim.time
                self.sim.log.warn(f'Oh no! I hit the wall! (Clamping from [x={self.x:f}, y={SIZE - self.y:f}])')
            self.x = min(max(self.x, 0.0), SIZE)
            self.y = min(max(self.y, 0.0), SIZE)

        if has_subscribers(self.pose_pub):
            self.pose_pub.publish({'x': self.x, 'y': self.y, 'theta': self.theta,
                                   'linear_velocity': math.hypot(self.lin_x, self.lin_y),
                                   'angular_velocity': self.ang})
        if has_subscribers(self.color_pub):
            r, g, b = self.sim.color_at(self.x, self.y)
            self.color_pub.publish({'r': r, 'g': g, 'b': b})
        if (self.x, self.y) != old:
            self.draw(old)

    def draw(self, old: tuple[float, float]) -> None:
        if not self.pen_on:
            return
        self.sim.draw_line(old, (self.x, self.y), self.pen)
        pts = self.pen_points
        if pts and pts[-1] == old and len(pts) >= 2:
            # extend the previous segment when the turtle keeps going straight
            (ax, ay), (bx, by) = pts[-2], pts[-1]
            cross = (bx - ax) * (self.y - by) - (by - ay) * (self.x - bx)
            dot = (bx - ax) * (self.x - bx) + (by - ay) * (self.y - by)
            if abs(cross) < 1e-9 and dot > 0:
                pts[-1] = (self.x, self.y)
                return
        pts += [old, (self.x, self.y)]

    def pen_marker(self) -> None:
        """Close the pen segments drawn since the last call into a marker (colour may change)."""
        if self.pen_points:
            r, g, b, width = self.pen
            self.pen_batch.append(mk.marker(   # the hub numbers it
                'pen', 0, mk.LINE_LIST, scale=(width / METER, 0, 0),
                rgba=mk.color(r / 255, g / 255, b / 255), points=[mk.point(x, y) for x, y in self.pen_points]))
            self.pen_points = []

    def robot_marker(self) -> dict:
        r, g, b = TURTLE_COLORS[self.index % len(TURTLE_COLORS)]
        rid = self.sim.hub.robot_id(f'{self.sim.node.name}/{self.name}')
        return mk.marker('robots', rid, mk.ARROW, pose=mk.pose(self.x, self.y, self.theta),
                         scale=(0.5, 0.25, 0.25), rgba=mk.color(r, g, b), text=self.name)


class Turtlesim:
    """The turtlesim node of one station (one namespace, one world)."""

    def __init__(self, graph, hub: mk.MarkerHub, namespace: str = '/', speed: float = 1.0):
        self.node = graph.node('turtlesim', namespace)
        self.hub, self.speed, self.time = hub, speed, 0.0
        self.log = RosLog(self.node, self.node.name.lstrip('/').replace('/', '.'))
        self.turtles: dict[str, Turtle] = {}
        self.id_counter = 0
        self.spawned = 0
        self.ticks = 0
        self.background = DEFAULT_BG
        self.path = Image.new('RGBA', (PIXELS, PIXELS), (255, 255, 255, 0))
        self.painter = ImageDraw.Draw(self.path)
        self.hub.add_layer(self.pen_layer)
        for i, channel in enumerate('rgb'):
            self.node.declare_parameter(f'background_{channel}', DEFAULT_BG[i],
                                        on_set=lambda v, i=i: self.on_background(i, v))
        self.node.declare_parameter('holonomic', False)
        self.node.declare_parameter('use_sim_time', False)
        self.node.create_service('spawn', 'turtlesim/srv/Spawn', self.on_spawn)
        self.node.create_service('kill', 'turtlesim/srv/Kill', self.on_kill)
        self.node.create_service('clear', 'std_srvs/srv/Empty', self.on_clear)
        self.node.create_service('reset', 'std_srvs/srv/Empty', self.on_reset)
        self.log.info(f'Starting turtlesim with node name {self.node.name}')
        self.hub.set_static(self.bounds_marker())
        self.spawn('', SIZE / 2, SIZE / 2, 0.0)
        self.node.create_timer(TICK, self.tick)

    def destroy(self) -> None:
        for turtle in list(self.turtles.values()):
            turtle.destroy()
        self.turtles.clear()
        self.node.destroy()

    # --- the frame ------------------------------------------------------------------------
    def tick(self) -> None:
        dt = TICK * self.speed
        self.time += dt
        for turtle in list(self.turtles.values()):
            turtle.update(dt)
        self.ticks += 1
        if self.ticks % MARKER_EVERY == 0:
            self.publish_markers()

    def publish_markers(self) -> None:
        for turtle in self.turtles.values():
            turtle.pen_marker()
            for m in turtle.pen_batch:
                self.hub.add_pen(m)
            turtle.pen_batch = []
            pose = (turtle.x, turtle.y, turtle.theta)
            if pose != turtle.last_marker_pose:
                turtle.last_marker_pose = pose
                self.hub.update(turtle.robot_marker())
        self.hub.flush()

    def bounds_marker(self) -> dict:
        r, g, b = (c / 255 for c in self.background)
        return mk.marker('bounds', 0, mk.CUBE, pose=mk.pose(SIZE / 2, SIZE / 2, 0.0, z=-0.01),
                         scale=(SIZE, SIZE, 0.01), rgba=mk.color(r, g, b))

    def pen_layer(self) -> list[dict]:
        """The trails drawn so far, for a viewer joining late: the raster's painted pixels."""
        return mk.raster_boxes(self.path, pixel=1 / METER, x0=0.0, y_top=SIZE, ns='pen',
                               id_base=mk.LAYER_ID_BASE)

    def draw_line(self, a: tuple[float, float], b: tuple[float, float], pen: tuple) -> None:
        r, g, bl, width = pen
        ends = [(round(x * METER), round((SIZE - y) * METER)) for x, y in (a, b)]
        self.painter.line(ends, fill=(r, g, bl, 255), width=width)

    def color_at(self, x: float, y: float) -> tuple[int, int, int]:
        px = min(max(round(x * METER), 0), PIXELS - 1)
        py = min(max(round((SIZE - y) * METER), 0), PIXELS - 1)
        r, g, b, _ = self.path.getpixel((px, py))  # unpainted: transparent white, as in the real node
        return r, g, b

    def on_background(self, index: int, value) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 255:
            self.node.params[f'background_{"rgb"[index]}'] = self.background[index]
            raise BackendError(f'background_{"rgb"[index]} must be an integer from 0 to 255')
        bg = list(self.background)
        bg[index] = value
        self.background = tuple(bg)
        self.hub.set_static(self.bounds_marker())

    # --- turtles --------------------------------------------------------------------------
    def spawn(self, name: str, x: float, y: float, theta: float) -> str:
        if not name:
            while True:
                self.id_counter += 1
                name = f'turtle{self.id_counter}'
                if name not in self.turtles:
                    break
        elif name in self.turtles:
            return ''
        if not NAME.match(name):
            raise BackendError(f'invalid turtle name {name!r}: it must be a valid ROS name')
        self.turtles[name] = Turtle(self, name, x, y, theta, self.spawned)
        self.spawned += 1
        self.log.info(f'Spawning turtle [{name}] at x=[{x:f}], y=[{y:f}], theta=[{theta:f}]')
        return name

    def remove(self, name: str) -> None:
        turtle = self.turtles.pop(name)
        turtle.pen_marker()
        for m in turtle.pen_batch:
            self.hub.add_pen(m)
        turtle.destroy()
        key = f'{self.node.name}/{name}'
        self.hub.update(mk.marker('robots', self.hub.robot_id(key), mk.ARROW, action=mk.DELETE))
        self.hub.forget_robot(key)

    def on_spawn(self, req: dict) -> dict:
        name = self.spawn(req.get('name', ''), float(req.get('x', 0.0)), float(req.get('y', 0.0)),
                          float(req.get('theta', 0.0)))
        if not name:
            self.log.error(f'A turtle named [{req.get("name", "")}] already exists')
        return {'name': name}

    def on_kill(self, req: dict) -> dict:
        name = req.get('name', '')
        if name not in self.turtles:
            self.log.error(f'Tried to kill turtle [{name}], which does not exist')
            return {}
        self.remove(name)
        return {}

    def clear(self) -> None:
        for turtle in self.turtles.values():  # segments drawn before the clear go with it
            turtle.pen_points, turtle.pen_batch = [], []
        self.path.paste((255, 255, 255, 0), (0, 0, PIXELS, PIXELS))
        self.hub.clear_pen()

    def on_clear(self, req: dict) -> dict:
        self.log.info('Clearing turtlesim.')
        self.clear()
        return {}

    def on_reset(self, req: dict) -> dict:
        self.log.info('Resetting turtlesim.')
        for name in list(self.turtles):
            self.remove(name)
        self.id_counter = 0
        self.spawned = 0
        self.spawn('', SIZE / 2, SIZE / 2, 0.0)
        self.clear()
        return {}
