"""Point clouds made to measure: a sensor_msgs/PointCloud2 thinned to the ``points`` a subscriber
asked for (the subscribe extension field, as ``image`` is for cameras and maps), so a page draws a
lidar for the cost of what it can show.

A 16-ring lidar's 5,760 points are 90 KB a cloud, a 64-ring one's 130,000 points 2-4 MB; a phone's
WebGL view shows a few thousand points usefully, and the JSON of a 2 MB cloud (base64) is 2.7 MB a
message. Thinned to 4,000 points of x, y, z and one colour or intensity field (16 bytes each) it is
64 KB whatever the sensor. Points are kept at an even stride through the cloud's own order (a
lidar's rings and a depth camera's rows stay evenly covered), after the points without a finite
x, y and z are dropped; the kept fields become little-endian float32 x, y, z at offsets 0, 4, 8
(float64 ones converted) and the first of ``rgb``, ``rgba`` or ``intensity`` (4 bytes, as it was)
at 12. A cloud of at most that many points comes back as sent. The work is numpy on strided views
of the data, done beside the loop as an image's render is (fanout.Renderer).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..media.images import ImageError

CLOUD = 'sensor_msgs/msg/PointCloud2'
INT32, UINT32, FLOAT32, FLOAT64 = 5, 6, 7, 8   # sensor_msgs/PointField datatypes
DTYPES = {FLOAT32: 'f4', FLOAT64: 'f8'}
EXTRA = ('rgb', 'rgba', 'intensity')
MAX_POINTS = 1_000_000


class CloudError(ImageError):
    """The message holds no cloud this module can read (its words say why)."""


@dataclass(frozen=True, slots=True)
class Target:
    """At most this many points (a subscriber's ``points``); hashable: one thinning per size, shared."""
    points: int


def thin(msg: dict, points: int) -> dict:
    """The cloud with at most ``points`` points of x, y, z (and a colour or intensity); raises CloudError."""
    width, height = int(msg.get('width', 0)), int(msg.get('height', 0))
    step = int(msg.get('point_step', 0))
    data = msg.get('data') or b''
    n = width * height
    if n == 0:
        return msg
    if step <= 0 or len(data) < n * step:
        raise CloudError(f'cannot thin the cloud: {width}x{height} points of {step} bytes do not fit its {len(data)} bytes')
    fields = {f.get('name'): f for f in msg.get('fields') or ()}
    order = '>' if msg.get('is_bigendian') else '<'
    columns = []
    for name in 'xyz':
        f = fields.get(name)
        if f is None or f.get('datatype') not in DTYPES or int(f.get('offset', -1)) + 4 * (f['datatype'] - 6) > step:
            raise CloudError(f'cannot thin the cloud: it has no float32 or float64 field {name!r}')
        columns.append(_column(data, n, step, int(f['offset']), order + DTYPES[f['datatype']]))
    xyz = np.stack(columns, axis=1)
    finite = np.flatnonzero(np.isfinite(xyz).all(axis=1))
    if n <= points and finite.size == n:
        return msg
    keep = finite if finite.size <= points else finite[(np.arange(points) * finite.size) // points]
    extra = next((fields[e] for e in EXTRA if e in fields and fields[e].get('datatype') in (INT32, UINT32, FLOAT32)
                  and int(fields[e].get('offset', -1)) + 4 <= step), None)
    out_step = 16 if extra is not None else 12
    out = np.empty((keep.size, out_step), np.uint8)
    out[:, :12] = np.ascontiguousarray(xyz[keep].astype('<f4')).view(np.uint8).reshape(-1, 12)
    if extra is not None:
        raw = np.frombuffer(data, np.uint8, count=n * step).reshape(n, step)
        field = raw[keep, int(extra['offset']):int(extra['offset']) + 4]
        out[:, 12:] = field[:, ::-1] if order == '>' else field
    kept = [{'name': c, 'offset': 4 * i, 'datatype': FLOAT32, 'count': 1} for i, c in enumerate('xyz')]
    if extra is not None:
        kept.append({'name': extra['name'], 'offset': 12, 'datatype': extra['datatype'], 'count': 1})
    return {'header': msg.get('header', {}), 'height': 1, 'width': int(keep.size), 'fields': kept,
            'is_bigendian': False, 'point_step': out_step, 'row_step': out_step * int(keep.size),
            'data': out.tobytes(), 'is_dense': True}


def _column(data, n: int, step: int, offset: int, dtype: str) -> np.ndarray:
    """One field of every point, as float64 (a strided view of the data, then one copy)."""
    return np.ndarray((n,), np.dtype(dtype), buffer=data, offset=offset, strides=(step,)).astype(np.float64)
