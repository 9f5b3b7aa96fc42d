"""The ``points`` extension field of subscribe: a sensor_msgs/PointCloud2 thinned by the gateway to
what a page can draw (bridge/clouds.py), in-process on made clouds and over the websocket on the
sim rover's 3D lidar."""

from __future__ import annotations

import base64

import numpy as np
import pytest

from gateway.bridge import clouds
from tests.support.rawclient import Raw

POINTS = '/points'
CLOUD = 'sensor_msgs/msg/PointCloud2'


def cloud(xyz: np.ndarray, *, dtype='<f4', rgb: np.ndarray | None = None, bigendian=False) -> dict:
    """A PointCloud2 of the given points, with 4 bytes of padding after z and an rgb field after that."""
    dt = np.dtype(dtype).newbyteorder('>' if bigendian else '<')
    size = dt.itemsize
    names = [('x', dt), ('y', dt), ('z', dt), ('pad', 'u1', (4,))]
    if rgb is not None:
        names.append(('rgb', np.dtype('u4').newbyteorder('>' if bigendian else '<')))
    rec = np.zeros(len(xyz), dtype=names)
    rec['x'], rec['y'], rec['z'] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    if rgb is not None:
        rec['rgb'] = rgb
    fields = [{'name': n, 'offset': i * size, 'datatype': 7 if size == 4 else 8, 'count': 1} for i, n in enumerate('xyz')]
    if rgb is not None:
        fields.append({'name': 'rgb', 'offset': 3 * size + 4, 'datatype': 6, 'count': 1})
    return {'header': {'stamp': {'sec': 1, 'nanosec': 2}, 'frame_id': 'lidar'}, 'height': 1, 'width': len(xyz),
            'fields': fields, 'is_bigendian': bigendian, 'point_step': rec.dtype.itemsize,
            'row_step': rec.dtype.itemsize * len(xyz), 'data': rec.tobytes(), 'is_dense': False}


def xyz_of(msg: dict) -> np.ndarray:
    data = msg['data'] if isinstance(msg['data'], bytes) else base64.b64decode(msg['data'])
    step = msg['point_step']
    raw = np.frombuffer(data, np.uint8).reshape(-1, step)
    return np.ascontiguousarray(raw[:, :12]).view('<f4').reshape(-1, 3)


def test_thinning_keeps_at_most_the_points_asked_for_evenly():
    xyz = np.arange(30_000, dtype=np.float64).reshape(-1, 3)
    xyz[5] = np.nan                                    # a point with no return
    rgb = np.arange(10_000, dtype=np.uint32)
    for kwargs in ({}, {'dtype': '<f8'}, {'bigendian': True}):
        msg = clouds.thin(cloud(xyz, rgb=rgb, **kwargs), 1000)
        assert msg['width'] == 1000 and msg['height'] == 1 and msg['point_step'] == 16
        assert [f['name'] for f in msg['fields']] == ['x', 'y', 'z', 'rgb'] and not msg['is_bigendian']
        kept = xyz_of(msg)
        assert np.isfinite(kept).all()
        index = (kept[:, 0] / 3).astype(int)            # every kept point is one of the cloud's own
        assert np.array_equal(kept, xyz[index].astype(np.float32))
        colours = np.frombuffer(msg['data'], np.uint8).reshape(-1, 16)[:, 12:].copy().view('<u4').ravel()
        assert np.array_equal(colours, rgb[index]), kwargs
        gaps = np.diff(index)
        assert gaps.min() >= 9 and gaps.max() <= 11, kwargs   # an even stride through the cloud


def test_a_small_cloud_passes_and_a_bad_one_is_said():
    small = cloud(np.ones((10, 3)))
    assert clouds.thin(small, 1000) is small
    with pytest.raises(clouds.CloudError, match="no float32 or float64 field 'z'"):
        clouds.thin({**small, 'fields': small['fields'][:2]}, 5)
    with pytest.raises(clouds.CloudError, match='do not fit'):
        clouds.thin({**small, 'data': small['data'][:50]}, 5)


@pytest.fixture(scope='module')
def rover(start_gateway):
    return start_gateway('--robot', 'rover')


def publish_of(c: Raw, id: str) -> dict:
    return c.expect(lambda m: m.get('op') == 'publish' and m.get('topic') == POINTS, 20)['msg']


@pytest.mark.parametrize('compression', ['none', 'cbor'])
def test_the_rovers_lidar_thinned_for_a_page(rover, compression):
    with Raw(rover.ws_url) as full, Raw(rover.ws_url) as page:
        full.send({'op': 'subscribe', 'topic': POINTS, 'id': 'full', 'type': CLOUD})
        page.send({'op': 'subscribe', 'topic': POINTS, 'id': 'page', 'points': 500, 'compression': compression})
        original, thinned = publish_of(full, 'full'), publish_of(page, 'page')
        assert original['width'] > 2000 and [f['name'] for f in original['fields']] == ['x', 'y', 'z', 'intensity']
        assert thinned['width'] == 500 and thinned['point_step'] == 16
        assert thinned['header']['frame_id'] == original['header']['frame_id'] == 'lidar_link'
        # the rover stands still: its cloud is the same each time, and the thinned one is part of it
        every = {tuple(p) for p in xyz_of(original).tolist()}
        assert all(tuple(p) in every for p in xyz_of(thinned).tolist())


def test_points_on_another_type_is_refused_with_a_status(rover):
    with Raw(rover.ws_url) as c:
        c.send({'op': 'subscribe', 'topic': '/odom', 'id': 'wrong', 'points': 10})
        status = c.expect(lambda m: m.get('op') == 'status' and m.get('id') == 'wrong', 10)
        assert status['level'] == 'error' and "'points' applies to sensor_msgs/msg/PointCloud2" in status['msg']
        c.send({'op': 'subscribe', 'topic': POINTS, 'id': 'zero', 'points': 0})
        status = c.expect(lambda m: m.get('op') == 'status' and m.get('id') == 'zero', 10)
        assert 'points' in status['msg'] and 'must be >= 1' in status['msg']
