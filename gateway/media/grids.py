"""Maps made to measure: a nav_msgs/OccupancyGrid shrunk to fit the ``image`` size a subscriber
asked for (the same field of subscribe as a camera's), so a page draws a big map for the cost of
a small one. A 4000x4000 map (0.05 m: a 200 m building floor) is 16 MB of int8 cells per update,
some 48 MB as JSON numbers; fitted into 512x512 it is 262 KiB as a CBOR typed array, the size a
phone's canvas can show anyway. Each cell of the smaller grid is the most occupied of the cells it
covers (unknown only when all of them are), so a wall one cell thick survives any shrinking.
"""

from __future__ import annotations

import math

import numpy as np

GRID = 'nav_msgs/msg/OccupancyGrid'


class GridError(ValueError):
    """The message holds no grid this module can read."""


def shrink(msg: dict, width: int | None, height: int | None) -> dict:
    """The grid fitted into width x height cells (None: no bound on that side); unchanged when it fits."""
    info = msg.get('info') or {}
    w, h = int(info.get('width', 0)), int(info.get('height', 0))
    data = msg.get('data')
    cells = np.asarray(data if data is not None else [], dtype=np.int16).ravel()
    if w <= 0 or h <= 0 or cells.size < w * h:
        raise GridError(f'grid of {w}x{h} does not fit its {cells.size} cells')
    k = max(1, math.ceil(w / width) if width else 1, math.ceil(h / height) if height else 1)
    if k == 1:
        return msg
    sw, sh = math.ceil(w / k), math.ceil(h / k)
    padded = np.full((sh * k, sw * k), -1, np.int16)
    padded[:h, :w] = cells[:w * h].reshape(h, w)
    small = padded.reshape(sh, k, sw, k).max(axis=(1, 3)).astype(np.int8)   # -1 only where all are unknown
    return {'header': msg.get('header', {}),
            'info': {**info, 'width': sw, 'height': sh, 'resolution': float(info.get('resolution', 0.0)) * k},
            'data': small.ravel().tolist()}
