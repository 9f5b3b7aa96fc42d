"""The world view: visualization_msgs/msg/MarkerArray on ``world/markers`` (latched).

One ``MarkerHub`` per namespace collects what every robot of that namespace shows. Frame
"world", metres. Namespaces (marker.ns): "bounds" (LINE_STRIP outline), "walls" (CUBEs),
"pen" (LINE_LIST batches, fresh id each, and the raster's CUBE_LISTs; DELETEALL before /clear
and /reset), "robots" (one ARROW per robot, stable id, name in marker.text; DELETE when it
goes), "scan" (POINTS).

Live subscribers receive increments (~10 Hz); the latched message is always a full snapshot,
so a viewer that subscribes late still sees bounds, walls, all pen trails and the robots.

The pen trails of a snapshot come from the robots' rasters (``add_layer``; turtlesim's 500x500
pen image, as the real node keeps its trails): CUBE_LISTs whose boxes, one pixel high, are the
painted runs of each pixel row, a marker per colour and box length (``raster_boxes``). Its size
is bounded by the raster, not by the length of the lesson, and it is built only when a viewer
joins. Live viewers get each batch once; after 1 to 2 times ``PEN_MARKERS_BEFORE_REFRESH``
batches (drawn at random per hub, so that the stations of a fleet, started together, do not all
build their rasters' markers in the same moment) they get a DELETEALL of "pen" and the raster's
markers in their place, so what they hold stays bounded too.
"""

from __future__ import annotations

import itertools
import random
from collections.abc import Callable
from typing import Any

import numpy as np

from ...base import QoS
from .msgs import IDENTITY_Q, header, has_subscribers, set_latched, vector3, yaw_quaternion

Message = dict[str, Any]
ARROW, CUBE, LINE_STRIP, LINE_LIST, CUBE_LIST, POINTS = 0, 1, 4, 5, 6, 8
ADD, DELETE, DELETEALL = 0, 2, 3
TYPE = 'visualization_msgs/msg/MarkerArray'
PEN_MARKERS_BEFORE_REFRESH = 1200   # live pen batches (2 minutes of a turtle) before the raster may replace them
LAYER_ID_BASE = 1_000_000_000       # ids of the markers of a raster layer (live batches count from 1)
RASTER_BYTES = 800_000              # about the most JSON a raster's markers take: coarser cells beyond
RASTER_LONGEST = 32                 # cells: longer runs are cut, so there are at most 32 box sizes
RASTER_OVERLAP = 0.5                # cells added to a box's size: neighbours overlap, no seam between them
RASTER_FEW_COLOURS = 16             # up to this many a marker per colour and size; beyond, a colour per box
BOX_BYTES, COLOURED_BOX_BYTES, MARKER_BYTES = 31, 70, 600   # JSON, about, for RASTER_BYTES


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


def raster_boxes(rgba, *, pixel: float, x0: float, y_top: float, ns: str, id_base: int,
                 frame_id: str = 'world', budget: int = RASTER_BYTES) -> list[Message]:
    """The painted pixels of an RGBA raster as CUBE_LIST markers.

    ``rgba``: (rows, columns, 4) uint8, row 0 at the top; a pixel is painted when its alpha is
    not 0. Pixel (column c, row r) is the square of side ``pixel`` metres centred at
    (x0 + c * pixel, y_top - r * pixel). Each run of same-coloured painted pixels along a row is
    a box one pixel high (runs longer than ``RASTER_LONGEST`` are cut), given by its centre
    alone, to the millimetre: a marker holds the boxes of one colour and one length, their size
    in its scale, a little larger than their pixels (``RASTER_OVERLAP``) so that no seam shows
    between neighbours where a viewer antialiases, as a browser's canvas does. Past
    ``RASTER_FEW_COLOURS`` colours a marker holds the boxes of one length in every colour, each
    box with its own (in ``colors``). Should that come to more than about ``budget`` bytes of JSON, the raster is read
    in square cells of 2, 3, ... pixels (a cell takes one of its painted colours) until it does
    not, so the markers stay under the budget whatever was drawn.
    """
    a = np.asarray(rgba)
    rows, cols = a.shape[:2]
    key = ((a[:, :, 0].astype(np.int32) << 16) | (a[:, :, 1].astype(np.int32) << 8) | a[:, :, 2])
    key[a[:, :, 3] == 0] = -1
    for cell in itertools.count(1):
        if cell == 1:
            grid = key
        else:
            h, w = -(-rows // cell), -(-cols // cell)
            padded = np.full((h * cell, w * cell), -1, dtype=np.int32)
            padded[:rows, :cols] = key
            grid = padded.reshape(h, cell, w, cell).max(axis=(1, 3))
        row, start, length, colour = _boxes(grid)
        few = len(np.unique(colour)) <= RASTER_FEW_COLOURS
        group = colour.astype(np.int64) * (RASTER_LONGEST + 1) + length if few else length
        cost = len(row) * (BOX_BYTES if few else COLOURED_BOX_BYTES) + len(np.unique(group)) * MARKER_BYTES
        if cost <= budget or grid.size * COLOURED_BOX_BYTES <= budget:
            break
    if not len(row):
        return []
    order = np.argsort(group, kind='stable')                                # row-major within a group
    group, row, start, length, colour = group[order], row[order], start[order], length[order], colour[order]
    xs = np.round(x0 + ((start + length / 2) * cell - 0.5) * pixel, 3).tolist()
    ys = np.round(y_top - (row * cell + (cell - 1) / 2) * pixel, 3).tolist()
    bounds = (np.flatnonzero(np.diff(group)) + 1).tolist()
    colours = colour.tolist()

    def rgba_of(value: int, digits: int | None = None) -> Message:
        rgb = [c / 255 for c in (value >> 16, (value >> 8) & 255, value & 255)]
        return color(*(rgb if digits is None else [round(c, digits) for c in rgb]))

    # many colours: one dict per colour shared by its boxes, three decimals (enough for 8 bits)
    palette = {} if few else {c: rgba_of(c, 3) for c in set(colours)}
    out = []
    for n, (begin, end) in enumerate(zip([0, *bounds], [*bounds, len(group)])):
        size = int(length[begin])
        m = marker(ns, id_base + n, CUBE_LIST, frame_id=frame_id,
                   scale=((size + RASTER_OVERLAP) * cell * pixel, (1 + RASTER_OVERLAP) * cell * pixel, 0.001),
                   rgba=rgba_of(colours[begin]) if few else color(1, 1, 1),
                   points=[{'x': xs[i], 'y': ys[i], 'z': 0.0} for i in range(begin, end)])
        if not few:
            m['colors'] = [palette[c] for c in colours[begin:end]]
        out.append(m)
    return out


def _boxes(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The runs of equal values >= 0 along the rows of ``grid``, cut to ``RASTER_LONGEST``: the
    row, first column, length and value of each, in row-major order."""
    row, first, last = _runs(grid)
    pieces = (last - first) // RASTER_LONGEST + 1
    run = np.repeat(np.arange(len(row)), pieces)
    start = first[run] + (np.arange(len(run)) - np.repeat(np.cumsum(pieces) - pieces, pieces)) * RASTER_LONGEST
    return row[run], start, np.minimum(last[run] - start + 1, RASTER_LONGEST), grid[row[run], first[run]]


def _runs(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The runs of equal values >= 0 along the rows of ``grid``: the row, first and last column
    of each, in row-major order."""
    edge = np.full((grid.shape[0], 1), -1, dtype=grid.dtype)
    painted = grid >= 0
    row, first = np.nonzero(painted & (grid != np.hstack((edge, grid[:, :-1]))))
    _, last = np.nonzero(painted & (grid != np.hstack((grid[:, 1:], edge))))   # the same runs, in order
    return row, first, last


class MarkerHub:
    """Collects markers of one namespace; publishes increments and keeps the latched snapshot."""

    def __init__(self, node, topic: str = 'world/markers'):
        self.pub = node.create_publisher(topic, TYPE, QoS(depth=1, transient_local=True))
        self.static: dict[tuple[str, int], Message] = {}    # bounds, walls: (ns, id) -> marker
        self.dynamic: dict[tuple[str, int], Message] = {}   # robots, scan: latest of each
        self.layers: list[Callable[[], list[Message]]] = []   # the pen rasters' markers, built on demand
        self.pending: list[Message] = []
        self.live_pen = 0                                   # pen batches sent since the last DELETEALL
        self.refresh_after = self._refresh_after()          # ... before the rasters' markers replace them
        self._ids = itertools.count(1)
        self._robot_ids: dict[str, int] = {}
        self._robot_counter = itertools.count(1)
        set_latched(self.pub, self.snapshot)

    def robot_id(self, key: str) -> int:
        """A stable marker id per robot (key: node name and robot name), until ``forget_robot``."""
        rid = self._robot_ids.get(key)
        if rid is None:
            rid = self._robot_ids[key] = next(self._robot_counter)
        return rid

    def forget_robot(self, key: str) -> None:
        """The robot is gone (its DELETE sent): a robot of that name later gets a fresh id."""
        self._robot_ids.pop(key, None)

    def add_layer(self, layer: Callable[[], list[Message]]) -> None:
        """``layer()``: the pen markers of everything drawn so far (a raster's ``raster_boxes``)."""
        self.layers.append(layer)

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
        """A batch of pen segments for live viewers (late viewers get the layers instead)."""
        m['id'] = next(self._ids)
        self.pending.append(m)
        self.live_pen += 1

    def clear_pen(self) -> None:
        self._delete_pen()

    def _delete_pen(self) -> None:
        self.pending.append(marker('pen', 0, LINE_LIST, action=DELETEALL))
        self.live_pen = 0
        self.refresh_after = self._refresh_after()
        self._ids = itertools.count(1)

    @staticmethod
    def _refresh_after() -> int:
        return PEN_MARKERS_BEFORE_REFRESH + random.randrange(PEN_MARKERS_BEFORE_REFRESH)

    def layer_markers(self) -> list[Message]:
        return [m for layer in self.layers for m in layer()]

    def snapshot(self) -> Message:
        return {'markers': [*self.static.values(), *self.layer_markers(), *self.dynamic.values()]}

    def flush(self) -> None:
        """Send what changed since the last flush to live subscribers.

        A subscriber gets a snapshot of the moment it subscribes, then every later increment,
        so it never misses a change (an increment may repeat what its snapshot had).
        """
        if self.live_pen >= self.refresh_after:
            self._delete_pen()
            if has_subscribers(self.pub):   # the batches they hold give way to the rasters (and the
                # rest comes again, for viewers whose DELETEALL clears every namespace)
                self.pending += [*self.layer_markers(), *self.static.values(), *self.dynamic.values()]
        if not self.pending:
            return
        if has_subscribers(self.pub):
            self.pub.publish({'markers': self.pending})
        self.pending = []
        set_latched(self.pub, self.snapshot)
