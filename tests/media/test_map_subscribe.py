"""A map made to measure: the ``image`` field of subscribe on a nav_msgs/OccupancyGrid topic
shrinks the grid in the fan-out (grids.py), so a page draws a 4000x4000 map for some 260 KiB an
update instead of 16 MB; walls one cell thick survive, unknown stays unknown."""

from __future__ import annotations

import array

import cbor2
import numpy as np
import pytest

from protocol.codec import decode_binary, typed_array_tag
from tests.support.rawclient import Raw

TOPIC = '/map'
SIDE = 4000
INFO = {'map_load_time': {'sec': 0, 'nanosec': 0}, 'resolution': 0.05, 'width': SIDE, 'height': SIDE,
        'origin': {'position': {'x': -100.0, 'y': -100.0, 'z': 0.0},
                   'orientation': {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}}}


@pytest.fixture(scope='module')
def gw(start_gateway):
    return start_gateway('--robot', 'none', '--max-message-size', str(24 * 2**20))


def big_map() -> np.ndarray:
    """Free floor, the left quarter unknown, one wall one cell thick along row 2001."""
    cells = np.zeros((SIDE, SIDE), np.int8)
    cells[:, :SIDE // 4] = -1
    cells[2001, :] = 100
    return cells


def test_a_4000_square_map_costs_a_few_hundred_kib(gw):
    cells = big_map()
    with Raw(gw.ws_url) as pub, Raw(gw.ws_url) as small, Raw(gw.ws_url) as whole:
        pub.send({'op': 'advertise', 'topic': TOPIC, 'type': 'nav_msgs/msg/OccupancyGrid', 'latch': True})
        pub.sync()
        msg = {'header': {'stamp': {'sec': 1, 'nanosec': 0}, 'frame_id': 'map'}, 'info': INFO,
               'data': typed_array_tag(array.array('b', cells.tobytes()))}
        pub.ws.send(cbor2.dumps({'op': 'publish', 'topic': TOPIC, 'msg': msg}))
        small.send({'op': 'subscribe', 'topic': TOPIC, 'id': 'small', 'compression': 'cbor',
                    'image': {'width': 512, 'height': 512}})
        frame = small.ws.recv(timeout=60)
        assert isinstance(frame, bytes)
        op = decode_binary(frame)   # the int8[] cells come as a typed array: one byte each
        assert op['op'] == 'publish', op
        info, data = op['msg']['info'], np.array(op['msg']['data'], np.int8)
        assert (info['width'], info['height']) == (500, 500)                # 4000 / 8
        assert info['resolution'] == pytest.approx(0.4)
        assert info['origin']['position']['x'] == -100.0
        grid = data.reshape(500, 500)
        assert (grid[250, :] == 100).all()                                  # the wall: row 2001 // 8
        assert (grid[:250, :125] == -1).all() and (grid[251:, :125] == -1).all() and (grid[:250, 125:] == 0).all()
        print(f'map {SIDE}x{SIDE}: {cells.nbytes} B of cells; shrunk to 512: {len(frame)} B per update (CBOR)')
        assert len(frame) < 300 * 1024

        # without the field: the whole map, as before
        whole.send({'op': 'subscribe', 'topic': TOPIC, 'id': 'all', 'compression': 'cbor'})
        full = whole.ws.recv(timeout=60)
        assert isinstance(full, bytes) and len(full) > SIDE * SIDE


def test_a_map_that_fits_passes_as_it_is_and_a_bad_one_gets_a_warning(gw):
    with Raw(gw.ws_url) as pub, Raw(gw.ws_url) as sub:
        pub.send({'op': 'advertise', 'topic': '/small_map', 'type': 'nav_msgs/msg/OccupancyGrid'})
        pub.sync()   # advertised before the other connection subscribes without a type
        sub.send({'op': 'subscribe', 'topic': '/small_map', 'image': {'width': 64}})
        sub.sync()
        info = {**INFO, 'width': 4, 'height': 2}
        pub.send({'op': 'publish', 'topic': '/small_map', 'msg': {'info': info, 'data': [0, 100, -1, 50, 0, 0, 0, 0]}})
        got = sub.expect(lambda m: m.get('op') == 'publish', 10)
        assert got['msg']['data'] == [0, 100, -1, 50, 0, 0, 0, 0] and got['msg']['info']['width'] == 4
        pub.send({'op': 'publish', 'topic': '/small_map', 'msg': {'info': {**info, 'width': 40}, 'data': [0, 1]}})
        warning = sub.expect(lambda m: m.get('op') == 'status', 10)
        assert warning['level'] == 'warning' and '/small_map' in warning['msg'] and 'map' in warning['msg']
