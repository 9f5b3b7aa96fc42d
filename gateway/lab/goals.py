"""An exercise's goal, written as data, turned into an evaluator the checker feeds.

A goal is JSON, never code, so a teacher's file or a POST cannot run anything on the gateway:

- ``{"region": {"xmin": 7, "xmax": 10, "ymin": 7, "ymax": 10}}``: the robot's pose has been inside
  the rectangle (sticky: reached once is reached).
- ``{"within": 20}``: seconds since the attempt began; true until then, false for ever after.
- ``{"clearance": 0.5}``: never closer than 0.5 m to the walls, measured on the robot's own
  LaserScan (smallest valid range) and, when the goal names ``"walls"`` (a rectangle, default the
  sim's turtlesim world 0..11.09), on the pose's distance to them. Violated once is violated.
- ``{"topic": "/count", "field": "data", "op": ">=", "value": 3}``: a topic's field reached a value
  (ops ``== != < <= > >=``; field a dotted path).
- ``{"all": [...]}``, ``{"any": [...]}``: combinations.

Each node answers ``verdict()``: True (met now), False (can never be met), None (not yet). The
attempt passes when the root says True, fails when it says False, and a root still None at the time
limit or the program's stop fails. ``score()`` is 1 for a met leaf else 0, the mean over ``all`` and
the best over ``any``: a partial credit that says how many parts a failed attempt reached.
``missed()`` says in words which parts were not met (the gradebook's comment: "failed (stopped)"
told a teacher nothing of what to look at).
"""

from __future__ import annotations

import math
import operator
from typing import Any

TURTLESIM_WALLS = {'xmin': 0.0, 'xmax': 11.088889, 'ymin': 0.0, 'ymax': 11.088889}
_OPS = {'==': operator.eq, '!=': operator.ne, '<': operator.lt, '<=': operator.le,
        '>': operator.gt, '>=': operator.ge}
MAX_DEPTH = 8
MAX_NODES = 64


class GoalError(ValueError):
    """The goal data is not one this module knows; the message names the part."""


def pose_of(msg: dict) -> tuple[float, float] | None:
    """(x, y) from a turtlesim/Pose, a geometry_msgs Pose(Stamped) or a nav_msgs/Odometry."""
    if not isinstance(msg, dict):
        return None
    if 'x' in msg and 'y' in msg and isinstance(msg['x'], (int, float)):
        return float(msg['x']), float(msg['y'])
    for path in (('pose', 'pose', 'position'), ('pose', 'position'), ('position',)):
        cur: Any = msg
        for key in path:
            cur = cur.get(key) if isinstance(cur, dict) else None
        if isinstance(cur, dict) and 'x' in cur and 'y' in cur:
            return float(cur['x']), float(cur['y'])
    return None


def scan_min(msg: dict) -> float | None:
    """Smallest valid range of a sensor_msgs/LaserScan (within range_min..range_max), or None."""
    lo, hi = float(msg.get('range_min', 0.0) or 0.0), float(msg.get('range_max', math.inf) or math.inf)
    valid = [float(r) for r in msg.get('ranges', ()) if r is not None
             and math.isfinite(float(r)) and lo <= float(r) <= hi]
    return min(valid) if valid else None


def field_of(msg: Any, path: str) -> Any:
    cur = msg
    for key in (path.split('.') if path else ()):
        if isinstance(cur, dict) and key in cur:
            cur = cur[key]
        elif isinstance(cur, list) and key.isdigit() and int(key) < len(cur):
            cur = cur[int(key)]
        else:
            return None
    return cur


class Node:
    def verdict(self) -> bool | None:
        raise NotImplementedError

    def score(self) -> float:
        return 1.0 if self.verdict() is True else 0.0

    def leaves(self) -> list['Node']:
        return [self]

    def missed(self) -> list[str]:
        """What of this part was not met, in words ([] when it was)."""
        return [] if self.verdict() is True else [self.shortfall()]

    def shortfall(self) -> str:
        raise NotImplementedError

    def on_pose(self, x: float, y: float) -> None:
        """A pose from the robot's own topic."""

    def on_scan(self, msg: dict) -> None:
        """A LaserScan from the robot's own topic."""

    def on_topic(self, topic: str, msg: Any) -> None:
        """A message on any topic the goal watches."""

    def on_time(self, t: float) -> None:
        """Seconds since the attempt began."""


class Region(Node):
    def __init__(self, spec: dict):
        try:
            self.box = {k: float(spec[k]) for k in ('xmin', 'xmax', 'ymin', 'ymax')}
        except (KeyError, TypeError, ValueError):
            raise GoalError('region needs numbers xmin, xmax, ymin, ymax') from None
        if self.box['xmin'] > self.box['xmax'] or self.box['ymin'] > self.box['ymax']:
            raise GoalError('region: min above max')
        self.reached = False

    def on_pose(self, x, y):
        b = self.box
        if b['xmin'] <= x <= b['xmax'] and b['ymin'] <= y <= b['ymax']:
            self.reached = True

    def verdict(self):
        return True if self.reached else None

    def shortfall(self):
        b = self.box
        return f'region x {b["xmin"]:g}..{b["xmax"]:g}, y {b["ymin"]:g}..{b["ymax"]:g} not reached'


class Within(Node):
    def __init__(self, seconds):
        if not isinstance(seconds, (int, float)) or isinstance(seconds, bool) or seconds <= 0:
            raise GoalError('within needs a positive number of seconds')
        self.limit, self.t = float(seconds), 0.0

    def on_time(self, t):
        self.t = max(self.t, t)

    def verdict(self):
        return self.t <= self.limit

    def shortfall(self):
        return f'took {self.t:.1f} s, over the {self.limit:g} s allowed'


class Clearance(Node):
    def __init__(self, distance, walls: dict | None):
        if not isinstance(distance, (int, float)) or isinstance(distance, bool) or distance < 0:
            raise GoalError('clearance needs a distance >= 0')
        self.distance = float(distance)
        self.walls = Region(walls or TURTLESIM_WALLS).box
        self.closest = math.inf

    def _near(self, d: float) -> None:
        self.closest = min(self.closest, d)

    def on_pose(self, x, y):
        w = self.walls
        self._near(min(x - w['xmin'], w['xmax'] - x, y - w['ymin'], w['ymax'] - y))

    def on_scan(self, msg):
        d = scan_min(msg)
        if d is not None:
            self._near(d)

    def verdict(self):
        return False if self.closest < self.distance else True

    def shortfall(self):
        return f'came within {self.closest:.2f} m of a wall ({self.distance:g} m of clearance asked)'


class TopicValue(Node):
    def __init__(self, spec: dict):
        self.topic = spec.get('topic')
        if not isinstance(self.topic, str) or not self.topic.startswith('/'):
            raise GoalError('topic needs a name starting with /')
        self.field = spec.get('field', 'data')
        if not isinstance(self.field, str):
            raise GoalError('topic field must be a dotted path')
        op = spec.get('op', '==')
        if op not in _OPS:
            raise GoalError(f'topic op must be one of {" ".join(_OPS)}')
        if 'value' not in spec:
            raise GoalError('topic needs a value')
        self.op, self.value, self.reached = _OPS[op], spec['value'], False
        self.op_text = op

    def on_topic(self, topic, msg):
        if topic != self.topic or self.reached:
            return
        got = field_of(msg, self.field)
        try:
            self.reached = got is not None and bool(self.op(got, self.value))
        except TypeError:
            pass

    def verdict(self):
        return True if self.reached else None

    def shortfall(self):
        return f'{self.topic} {self.field} {self.op_text} {self.value!r} not reached'


class All(Node):
    def __init__(self, parts: list[Node]):
        self.parts = parts

    def leaves(self):
        return [leaf for p in self.parts for leaf in p.leaves()]

    def missed(self):
        return [m for p in self.parts for m in p.missed()]

    def verdict(self):
        vs = [p.verdict() for p in self.parts]
        return False if False in vs else (True if all(v is True for v in vs) else None)

    def score(self):
        return sum(p.score() for p in self.parts) / len(self.parts)


class Any_(All):
    def verdict(self):
        vs = [p.verdict() for p in self.parts]
        return True if True in vs else (False if all(v is False for v in vs) else None)

    def score(self):
        return max(p.score() for p in self.parts)

    def missed(self):
        if self.verdict() is True:
            return []
        return ['none of: ' + ' | '.join('; '.join(p.missed()) for p in self.parts)]


def build(spec: Any, _depth: int = 0, _count: list | None = None) -> Node:
    """Goal data → evaluator tree; GoalError names what is wrong. Bounded in depth and size."""
    count = _count if _count is not None else [0]
    count[0] += 1
    if _depth > MAX_DEPTH or count[0] > MAX_NODES:
        raise GoalError(f'goal too large (depth {MAX_DEPTH}, {MAX_NODES} parts at most)')
    if not isinstance(spec, dict) or not spec:
        raise GoalError('a goal is an object with one of: region, within, clearance, topic, all, any')
    if 'all' in spec or 'any' in spec:
        parts = spec.get('all', spec.get('any'))
        if not isinstance(parts, list) or not parts:
            raise GoalError('all/any need a non-empty list')
        nodes = [build(p, _depth + 1, count) for p in parts]
        return All(nodes) if 'all' in spec else Any_(nodes)
    if 'region' in spec:
        return Region(spec['region'] if isinstance(spec['region'], dict) else {})
    if 'within' in spec:
        return Within(spec['within'])
    if 'clearance' in spec:
        return Clearance(spec['clearance'], spec.get('walls'))
    if 'topic' in spec:
        return TopicValue(spec)
    raise GoalError(f'unknown goal {sorted(spec)}')


def topics_of(node: Node) -> set[str]:
    """The extra topics a goal watches (beyond the station's pose and scan)."""
    return {leaf.topic for leaf in node.leaves() if isinstance(leaf, TopicValue)}


class Evaluation:
    """One attempt's goal: feed observations, read ``outcome()``; ``finish()`` at the end."""

    def __init__(self, spec: Any):
        self.root = build(spec)
        self.t = 0.0

    def _each(self, event: str, *args) -> None:
        for leaf in self.root.leaves():
            getattr(leaf, event)(*args)

    def time(self, t: float) -> None:
        self.t = max(self.t, t)
        self._each('on_time', self.t)

    def pose(self, msg: dict) -> None:
        p = pose_of(msg)
        if p is not None:
            self._each('on_pose', *p)

    def scan(self, msg: dict) -> None:
        self._each('on_scan', msg)

    def topic(self, topic: str, msg: Any) -> None:
        self._each('on_topic', topic, msg)

    def outcome(self) -> bool | None:
        return self.root.verdict()

    def missed(self) -> str:
        """The parts of the goal not met, in words ('' when it is met)."""
        return '; '.join(self.root.missed())

    def finish(self) -> tuple[bool, float]:
        """(passed, score) when the attempt ends: a goal not yet met has failed."""
        passed = self.root.verdict() is True
        return passed, 1.0 if passed else round(self.root.score(), 4)
