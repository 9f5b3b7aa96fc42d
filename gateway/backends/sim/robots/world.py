"""Rover worlds: a rectangle with walls and obstacles, loaded from a small JSON file.

Format (metres, origin bottom-left, angles in radians)::

    {"name": "arena", "size": [10, 8], "start": [x, y, theta],
     "wall_height": 0.5, "floor": [r, g, b], "sky": [r, g, b],       # colours 0..1, optional
     "boxes": [{"center": [x, y], "size": [sx, sy], "yaw": 0, "color": [r, g, b]}],
     "lines": [{"from": [x, y], "to": [x, y], "thickness": 0.1, "color": [r, g, b]}]}

"lines" are walls given by their centre line; both become boxes. The outline is a wall too.
Geometry is held as numpy arrays of segments so ray casts and clearance checks are vectorised.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

WORLDS_DIR = Path(__file__).parent / 'worlds'
OUTLINE_COLOR = (0.55, 0.55, 0.6)


@dataclass(frozen=True)
class Box:
    x: float
    y: float
    sx: float
    sy: float
    yaw: float
    color: tuple[float, float, float]

    def corners(self) -> list[tuple[float, float]]:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        hx, hy = self.sx / 2, self.sy / 2
        return [(self.x + c * dx - s * dy, self.y + s * dx + c * dy)
                for dx, dy in ((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))]


class WorldError(ValueError):
    pass


class World:
    def __init__(self, name: str, width: float, height: float, start: tuple[float, float, float],
                 boxes: list[Box], wall_height: float = 0.5,
                 floor: tuple = (0.78, 0.76, 0.72), sky: tuple = (0.80, 0.88, 0.97)):
        self.name, self.width, self.height, self.start = name, width, height, start
        self.boxes, self.wall_height, self.floor, self.sky = boxes, wall_height, floor, sky
        segs, colors = [], []
        outline = [(0, 0), (width, 0), (width, height), (0, height)]
        for poly, color in [(outline, OUTLINE_COLOR), *((b.corners(), b.color) for b in boxes)]:
            for i in range(4):
                segs.append((*poly[i], *poly[(i + 1) % 4]))
                colors.append(color)
        arr = np.array(segs, dtype=np.float64)
        self.a = arr[:, :2]
        self.e = arr[:, 2:] - arr[:, :2]
        self.ee = np.einsum('ij,ij->i', self.e, self.e)
        self.colors = np.array(colors, dtype=np.float64)
        # boxes as centre, rotation and half sizes, for inside tests
        self.box_frames = np.array([(b.x, b.y, math.cos(b.yaw), math.sin(b.yaw), b.sx / 2, b.sy / 2)
                                    for b in boxes], dtype=np.float64).reshape(-1, 6)
        self.deepest = float(np.minimum(self.box_frames[:, 4], self.box_frames[:, 5]).max(initial=0.0))
        # segment direction parity, for side shading in the camera
        self.side = (np.abs(self.e[:, 0]) < np.abs(self.e[:, 1])).astype(np.float64)

    @classmethod
    def load(cls, spec: str) -> World:
        """A world by name (a file in worlds/) or by path to a JSON file."""
        path = Path(spec)
        if not path.suffix:
            path = WORLDS_DIR / f'{spec}.json'
        try:
            data = json.loads(path.read_text())
        except OSError as e:
            known = ', '.join(sorted(p.stem for p in WORLDS_DIR.glob('*.json')))
            raise WorldError(f'no world {spec!r} (known: {known}, or a path to a .json file): {e}') from None
        except json.JSONDecodeError as e:
            raise WorldError(f'world file {path} is not valid JSON: {e}') from None
        return cls.from_dict(data, default_name=path.stem)

    @classmethod
    def from_dict(cls, data: dict, default_name: str = 'world') -> World:
        try:
            width, height = (float(v) for v in data['size'])
            start = tuple(float(v) for v in data.get('start', (width / 2, height / 2, 0.0)))
            boxes = []
            for b in data.get('boxes', ()):
                boxes.append(Box(float(b['center'][0]), float(b['center'][1]), float(b['size'][0]),
                                 float(b['size'][1]), float(b.get('yaw', 0.0)),
                                 _color(b.get('color', (0.5, 0.5, 0.5)))))
            for ln in data.get('lines', ()):
                (x1, y1), (x2, y2) = ln['from'], ln['to']
                t = float(ln.get('thickness', 0.1))
                length = math.hypot(x2 - x1, y2 - y1)
                boxes.append(Box((x1 + x2) / 2, (y1 + y2) / 2, length + t, t,
                                 math.atan2(y2 - y1, x2 - x1), _color(ln.get('color', (0.5, 0.5, 0.5)))))
            kwargs = {k: _color(data[k]) for k in ('floor', 'sky') if k in data}
            world = cls(str(data.get('name', default_name)), width, height, start, boxes,
                        float(data.get('wall_height', 0.5)), **kwargs)
        except (KeyError, TypeError, ValueError, IndexError) as e:
            raise WorldError(f'malformed world description: {e!r}') from None
        if len(start) != 3 or width <= 0 or height <= 0:
            raise WorldError('a world needs a positive size and a start [x, y, theta]')
        return world

    def clearance(self, x: float, y: float) -> float:
        """Distance from a point to the nearest wall; negative inside a wall or outside the world."""
        px, py = x - self.a[:, 0], y - self.a[:, 1]
        t = np.clip((px * self.e[:, 0] + py * self.e[:, 1]) / self.ee, 0.0, 1.0)
        dx, dy = px - t * self.e[:, 0], py - t * self.e[:, 1]
        d = float(np.sqrt((dx * dx + dy * dy).min()))
        outside = not (0 <= x <= self.width and 0 <= y <= self.height)
        # a point inside a box is closer to its edges than the box's half width
        return -d if outside or (d <= self.deepest and self.inside_wall(x, y)) else d

    def inside_wall(self, x: float, y: float) -> bool:
        if not (0 <= x <= self.width and 0 <= y <= self.height):
            return True
        cx, cy, c, s, hx, hy = self.box_frames.T
        dx, dy = x - cx, y - cy
        return bool(np.any((np.abs(c * dx + s * dy) < hx) & (np.abs(-s * dx + c * dy) < hy)))

    def cast(self, x: float, y: float, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance along each ray to the first wall, and the index of the segment hit."""
        dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
        apx, apy = self.a[:, 0] - x, self.a[:, 1] - y
        ex, ey = self.e[:, 0], self.e[:, 1]
        denom = dx * ey - dy * ex
        with np.errstate(divide='ignore', invalid='ignore'):
            t = (apx * ey - apy * ex) / denom
            u = (apx * dy - apy * dx) / denom
        t = np.where((t > 0) & (u >= 0) & (u <= 1), t, np.inf)
        hit = t.argmin(axis=1)
        return t[np.arange(len(angles)), hit], hit


def _color(c) -> tuple[float, float, float]:
    r, g, b = (float(v) for v in c)
    return (r, g, b)
