"""The world view: visualization_msgs/msg/MarkerArray on ``world/markers`` (latched).

One ``MarkerHub`` per namespace collects what every robot of that namespace shows. Frame
"world", metres. Namespaces (marker.ns): "bounds" (LINE_STRIP outline), "walls" (CUBEs),
"pen" (LINE_LIST batches, fresh id each; DELETEALL before /clear and /reset), "robots" (one
ARROW per robot, stable id, name in marker.text; DELETE when it goes), "scan" (POINTS).

Live subscribers receive increments (~10 Hz); the latched message is always a full snapshot,
so a viewer that subscribes late still sees bounds, walls, all pen trails and the robots.
"""

from __future__ import annotations

from typing import Any

from ...base import QoS
from .msgs import IDENTITY_Q, header, has_subscribers, set_latched, vector3, yaw_quaternion

Message = dict[str, Any]
ARROW, CUBE, LINE_STRIP, LINE_LIST, POINTS = 0, 1, 4, 5, 8
ADD, DELETE, DELETEALL = 0, 2, 3
TYPE = 'visualization_msgs/msg/MarkerArray'
PEN_BATCHES_BEFORE_COMPACTION = 200
PEN_HISTORY_LIMIT = 200_000          # segments kept for late viewers
HISTORY_ID_BASE = 1_000_000_000      # ids of compacted pen history markers


def color(r: float, g: float, b: float, a: float = 1.0) -> Message:
    return {'r': float(r), 'g': float(g), 'b': float(b), 'a': float(a)}


def marker(ns: str, id: int, type: int, *, action: int = ADD, pose: Message | None = None,
           scale: tuple = (1.0, 1.0, 1.0), rgba: Message | None = None, points: list | None = None,
           text: str = '', frame_id: str = 'world') -> Message:
    return {
        'header': header(frame_id), 'ns': ns, 'id': id, 'type': type, 'action': action,
        'pose': pose or {'position': vector3(), 'orientation': dict(IDENTITY_Q)},
        'scale': vector3(*scale), 'color': rgba or color(1, 1, 1),
        'lifetime': {'sec': 0, 'nanosec': 0}, 'frame_locked': False,
        'points': points or [], 'colors': [], 'texture_resource': '',
        'texture': {'header': header(''), 'format': '', 'data': b''},
        'uv_coordinates': [], 'text': text, 'mesh_resource': '',
        'mesh_file': {'filename': '', 'data': b''}, 'mesh_use_embedded_materials': False,
    }


def point(x: float, y: float, z: float = 0.0) -> Message:
    return {'x': float(x), 'y': float(y), 'z': float(z)}


def pose(x: float, y: float, yaw: float, z: float = 0.0) -> Message:
    return {'position': point(x, y, z), 'orientation': yaw_quaternion(yaw)}


def outline(id: int, width: float, height: float, x0: float = 0.0, y0: float = 0.0) -> Message:
    corners = [(x0, y0), (x0 + width, y0), (x0 + width, y0 + height), (x0, y0 + height), (x0, y0)]
    return marker('bounds', id, LINE_STRIP, scale=(0.03, 0, 0), rgba=color(0.2, 0.2, 0.2),
                  points=[point(x, y) for x, y in corners])


class MarkerHub:
    """Collects markers of one namespace; publishes increments and keeps the latched snapshot."""

    def __init__(self, node, topic: str = 'world/markers'):
        self.pub = node.create_publisher(topic, TYPE, QoS(depth=1, transient_local=True))
        self.static: dict[tuple[str, int], Message] = {}    # bounds, walls: (ns, id) -> marker
        self.dynamic: dict[tuple[str, int], Message] = {}   # robots, scan: latest of each
        self.pen_batches: list[Message] = []               # pen markers not yet compacted
        self.pen_history: dict[tuple, Message] = {}         # (rgba, width) -> compacted LINE_LIST
        self.history_segments = 0
        self.pending: list[Message] = []
        self._ids = iter(range(1, HISTORY_ID_BASE))
        self._history_ids = iter(range(HISTORY_ID_BASE, 2**31 - 1))
        self._robot_ids: dict[str, int] = {}

    def robot_id(self, key: str) -> int:
        """A stable marker id per robot (key: node name and robot name)."""
        return self._robot_ids.setdefault(key, len(self._robot_ids) + 1)

    def next_pen_id(self) -> int:
        return next(self._ids)

    def set_static(self, m: Message) -> None:
        self.static[(m['ns'], m['id'])] = m
        self.pending.append(m)

    def update(self, m: Message) -> None:
        key = (m['ns'], m['id'])
        if m['action'] == DELETE:
            self.dynamic.pop(key, None)
            self.static.pop(key, None)
        else:
            self.dynamic[key] = m
        self.pending.append(m)

    def add_pen(self, m: Message) -> None:
        self.pen_batches.append(m)
        self.pending.append(m)
        if len(self.pen_batches) > PEN_BATCHES_BEFORE_COMPACTION:
            self._compact()

    def clear_pen(self) -> None:
        self.pen_batches.clear()
        self.pen_history.clear()
        self.history_segments = 0
        self.pending.append(marker('pen', 0, LINE_LIST, action=DELETEALL))

    def _compact(self) -> None:
        """Fold pen batches into one marker per (colour, width), for late viewers."""
        for m in self.pen_batches:
            c = m['color']
            key = (c['r'], c['g'], c['b'], c['a'], m['scale']['x'])
            hist = self.pen_history.get(key)
            if hist is None:
                hist = self.pen_history[key] = marker('pen', next(self._history_ids), LINE_LIST,
                                                      scale=(m['scale']['x'], 0, 0), rgba=dict(c),
                                                      frame_id=m['header']['frame_id'])
            hist['points'] = hist['points'] + m['points']
            self.history_segments += len(m['points']) // 2
        self.pen_batches.clear()
        while self.history_segments > PEN_HISTORY_LIMIT and self.pen_history:
            oldest = next(iter(self.pen_history))
            self.history_segments -= len(self.pen_history.pop(oldest)['points']) // 2

    def snapshot(self) -> Message:
        return {'markers': [*self.static.values(), *self.pen_history.values(), *self.pen_batches,
                            *self.dynamic.values()]}

    def flush(self) -> None:
        """Send what changed since the last flush to live subscribers; refresh the snapshot.

        A subscriber gets the snapshot of the last flush on subscribing, then every later
        increment, so it never misses a change.
        """
        if not self.pending:
            return
        if has_subscribers(self.pub):
            self.pub.publish({'markers': self.pending})
        self.pending = []
        set_latched(self.pub, self.snapshot())
