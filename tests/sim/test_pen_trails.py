"""Turtlesim's pen trails in the world view, in process: what a late viewer gets, what a live
viewer holds, and that neither grows with the length of the lesson.

The turtles are stepped by calling the node's tick directly (its timer never runs here), so
the tests count moves, entries and bytes, never time.
"""

from __future__ import annotations

import asyncio
import itertools
import math
import random

import numpy as np
import pytest

from gateway.backends.sim.graph import Graph
from gateway.backends.sim.robots import markers as mk
from gateway.backends.sim.robots.fleet import FramedHub
from gateway.backends.sim.robots.turtlesim import MARKER_EVERY, METER, PIXELS, SIZE, Turtlesim
from protocol.codec import dumps

TOPIC = '/world/markers'
TYPE = 'visualization_msgs/msg/MarkerArray'
_names = itertools.count(1)


class Viewer:
    """A world-view subscriber that keeps markers as the IDE's worldview.js does ('ns/id')."""

    def __init__(self, graph: Graph, name: str = 'viewer'):
        self.markers: dict[tuple[str, int], dict] = {}
        self.messages = 0
        self.largest = 0
        self.sub = graph.node(name).create_subscription(TOPIC, TYPE, self.receive)
        self.sub.catch_up()   # the snapshot, now rather than on the loop's next turn

    def receive(self, msg: dict) -> None:
        self.messages += 1
        self.largest = max(self.largest, len(dumps(msg)))
        for m in msg['markers']:
            if m['action'] == mk.DELETEALL:
                for key in [k for k in self.markers if not m['ns'] or k[0] == m['ns']]:
                    del self.markers[key]
            elif m['action'] == mk.DELETE:
                self.markers.pop((m['ns'], m['id']), None)
            else:
                self.markers[(m['ns'], m['id'])] = m

    def pen(self) -> list[dict]:
        return [m for (ns, _), m in self.markers.items() if ns == 'pen']


def in_loop(test):
    """Run a test body with a running event loop (the graph's nodes need one to exist)."""
    def run(*args, **kwargs):
        async def body():
            return test(*args, **kwargs)
        return asyncio.run(body())
    run.__name__, run.__doc__ = test.__name__, test.__doc__
    return run


def station(frame: str | None = None) -> tuple[Graph, mk.MarkerHub, Turtlesim]:
    graph = Graph()
    hub = mk.MarkerHub(graph.node('world_view'))
    sim = Turtlesim(graph, FramedHub(hub, frame) if frame else hub)
    hub.flush()
    return graph, hub, sim


def late_snapshot(graph: Graph) -> dict:
    """What a viewer subscribing now receives first."""
    got = []
    sub = graph.node(f'late{next(_names)}').create_subscription(TOPIC, TYPE, got.append)
    sub.catch_up()
    sub.destroy()
    assert len(got) == 1
    return got[0]


def pen_markers(msg: dict) -> list[dict]:
    return [m for m in msg['markers'] if m['ns'] == 'pen' and m['action'] == mk.ADD]


def painted_at(pens: list[dict], x: float, y: float, rgb: tuple | None = None) -> bool:
    """Whether a pen LINE_LIST (a live batch) covers the point (x, y) (within half its width)."""
    for m in pens:
        if rgb is not None and (round(m['color']['r'] * 255), round(m['color']['g'] * 255),
                                round(m['color']['b'] * 255)) != rgb:
            continue
        half = m['scale']['x'] / 2
        pts = m['points']
        for a, b in zip(pts[::2], pts[1::2]):
            ax, ay, bx, by = a['x'], a['y'], b['x'], b['y']
            dx, dy = bx - ax, by - ay
            length2 = dx * dx + dy * dy
            t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy) / length2))
            if math.hypot(ax + t * dx - x, ay + t * dy - y) <= half + 1e-6:
                return True
    return False


def teleport(sim: Turtlesim, x: float, y: float, theta: float = 0.0, turtle: str = 'turtle1') -> None:
    sim.turtles[turtle].on_teleport_absolute({'x': x, 'y': y, 'theta': theta})
    steps(sim, MARKER_EVERY)


def raster_of(pens: list[dict], cell: int = 1) -> np.ndarray:
    """The pixels a snapshot's boxes cover, as colour keys (-1: none), to set beside the
    turtlesim's own raster (boxes of ``cell`` pixels high)."""
    out = np.full((PIXELS, PIXELS), -1, dtype=np.int64)

    def key(c: dict) -> int:
        return (round(c['r'] * 255) << 16) | (round(c['g'] * 255) << 8) | round(c['b'] * 255)

    for m in pens:
        assert m['type'] == mk.CUBE_LIST
        assert m['scale']['y'] == pytest.approx((1 + mk.RASTER_OVERLAP) * cell / METER)
        length = round(m['scale']['x'] * METER - mk.RASTER_OVERLAP * cell)   # pixels
        colours = m['colors'] or [m['color']] * len(m['points'])
        for p, c in zip(m['points'], colours, strict=True):
            row = round((SIZE - p['y']) * METER - (cell - 1) / 2)
            first = round(p['x'] * METER - (length - 1) / 2)
            out[row:row + cell, first:first + length] = key(c)
    return out


def colour_at(pens: list[dict], x: float, y: float) -> tuple | None:
    """The colour a snapshot's runs give the pixel of (x, y), as turtlesim's colour sensor reads it."""
    key = int(raster_of(pens)[round((SIZE - y) * METER), round(x * METER)])
    return None if key < 0 else (key >> 16, (key >> 8) & 255, key & 255)


def raster_keys(sim: Turtlesim) -> np.ndarray:
    a = np.asarray(sim.path).astype(np.int64)
    keys = (a[:, :, 0] << 16) | (a[:, :, 1] << 8) | a[:, :, 2]
    keys[a[:, :, 3] == 0] = -1
    return keys


def steps(sim: Turtlesim, n: int) -> None:
    for _ in range(n):
        sim.tick()


def wander(sim: Turtlesim, moves: int, seed: int = 7) -> None:
    """Drive turtle1 with a command every 6 ticks (~10 Hz), turning at random."""
    rng = random.Random(seed)
    turtle = sim.turtles['turtle1']
    ang = 0.0
    for i in range(moves):
        if i % 6 == 0:
            ang = max(-2.5, min(2.5, ang + rng.uniform(-0.6, 0.6)))
            turtle.on_cmd_vel({'linear': {'x': 1.6, 'y': 0.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': ang}})
        sim.tick()


@in_loop
def test_a_point_drawn_is_in_the_late_snapshot_in_the_pen_colour():
    graph, hub, sim = station()
    turtle = sim.turtles['turtle1']
    turtle.on_set_pen({'r': 255, 'g': 0, 'b': 0, 'width': 3, 'off': 0})
    teleport(sim, 2.0, 3.0)                       # a red line from the centre to (2, 3)
    snap = late_snapshot(graph)
    pens = pen_markers(snap)
    assert pens and all(m['type'] == mk.CUBE_LIST and m['header']['frame_id'] == 'world' for m in pens)
    assert colour_at(pens, 2.0, 3.0) == (255, 0, 0)
    assert colour_at(pens, (2.0 + SIZE / 2) / 2, (3.0 + SIZE / 2) / 2) == (255, 0, 0)   # half way
    assert colour_at(pens, 8.0, 8.0) is None
    assert {'bounds', 'pen', 'robots'} <= {m['ns'] for m in snap['markers']}
    # boxes one pixel high: the snapshot is the raster the colour sensor reads
    assert np.array_equal(raster_of(pens), raster_keys(sim))
    assert sim.color_at(2.0, 3.0) == (255, 0, 0)


@in_loop
def test_pen_off_draws_nothing_and_a_new_colour_paints_over():
    graph, hub, sim = station()
    turtle = sim.turtles['turtle1']
    turtle.on_set_pen({'off': 1})
    teleport(sim, 9.0, 9.0)
    assert not pen_markers(late_snapshot(graph))
    turtle.on_set_pen({'r': 0, 'g': 0, 'b': 255, 'width': 5, 'off': 0})
    teleport(sim, 9.0, 2.0)                       # blue, down the right side
    turtle.on_set_pen({'r': 0, 'g': 200, 'b': 0, 'width': 1, 'off': 0})
    teleport(sim, 9.0, 5.0)                       # green over part of the blue
    pens = pen_markers(late_snapshot(graph))
    assert colour_at(pens, 9.0, 7.0) == (0, 0, 255)
    assert colour_at(pens, 9.0, 4.0) == (0, 200, 0)           # the last colour drawn on a pixel
    assert colour_at(pens, 9.0 + 2 / METER, 4.0) == (0, 0, 255)   # the wide blue pen shows beside it
    assert colour_at(pens, 9.0 + 3 / METER, 4.0) is None
    half_way = (9.0 + SIZE / 2) / 2                           # the pen was off from the centre to (9, 9)
    assert colour_at(pens, half_way, half_way) is None
    assert np.array_equal(raster_of(pens), raster_keys(sim))


@in_loop
def test_clear_and_reset_clear_the_trails():
    graph, hub, sim = station()
    teleport(sim, 2.0, 2.0)
    viewer = Viewer(graph)
    assert viewer.pen() and pen_markers(late_snapshot(graph))
    sim.on_clear({})
    steps(sim, MARKER_EVERY)
    assert not pen_markers(late_snapshot(graph))
    assert not viewer.pen()                           # the live viewer got the DELETEALL
    teleport(sim, 4.0, 2.0)
    assert colour_at(pen_markers(late_snapshot(graph)), 3.0, 2.0) is not None
    assert colour_at(pen_markers(late_snapshot(graph)), 3.0, 3.0) is None
    assert painted_at(viewer.pen(), 3.0, 2.0)
    sim.on_reset({})
    steps(sim, MARKER_EVERY)
    snap = late_snapshot(graph)
    assert not pen_markers(snap)
    assert not viewer.pen()
    robots = [m for m in snap['markers'] if m['ns'] == 'robots']
    assert [m['text'] for m in robots] == ['turtle1']


@in_loop
def test_the_trail_store_stays_bounded_after_100000_moves():
    """The hub, the turtle and both viewers hold no more after 100,000 moves than the raster allows."""
    graph, hub, sim = station()
    live = Viewer(graph)
    turtle = sim.turtles['turtle1']
    block = 20_004                                   # a whole number of flushes
    for n in range(5):
        wander(sim, block, seed=n)
        snap = late_snapshot(graph)
        pens = pen_markers(snap)
        # the hub keeps what a viewer needs and no pen history of its own
        assert not hub.pending and hub.live_pen < hub.refresh_after < 2 * mk.PEN_MARKERS_BEFORE_REFRESH
        assert len(hub.static) == 1 and len(hub.dynamic) == 1 and len(hub.layers) == 1
        assert len(turtle.pen_points) <= 2 * MARKER_EVERY and not turtle.pen_batch
        assert sim.path.size == (500, 500)
        # the late viewer's snapshot: within the raster's budget, under 1 MB of JSON
        assert len(dumps(pens)) <= mk.RASTER_BYTES
        assert len(dumps(snap)) < 1_000_000
        # the live viewer: the raster's markers and at most one refresh period of batches
        assert len(live.pen()) <= len(pens) + 2 * mk.PEN_MARKERS_BEFORE_REFRESH
    assert live.largest < 1_100_000
    # the lesson went on: the turtle covered ground, and the snapshot is exactly its raster
    assert live.messages >= 5 * block // MARKER_EVERY
    painted = (raster_keys(sim) >= 0).mean()
    assert painted > 0.2, painted
    pens = pen_markers(late_snapshot(graph))
    assert np.array_equal(raster_of(pens), raster_keys(sim))   # (in pixels: no coarser cells needed)
    # and the live viewer has drawn the last stretch too
    assert painted_at(live.pen(), turtle.x, turtle.y)


@in_loop
def test_a_live_viewer_gets_the_raster_in_place_of_its_batches():
    graph, hub, sim = station()
    live = Viewer(graph)
    turtle = sim.turtles['turtle1']
    turtle.on_set_pen({'r': 10, 'g': 20, 'b': 30, 'width': 2, 'off': 0})
    drawn = []
    assert mk.PEN_MARKERS_BEFORE_REFRESH <= hub.refresh_after < 2 * mk.PEN_MARKERS_BEFORE_REFRESH
    while hub.live_pen < hub.refresh_after - 1:
        wander(sim, MARKER_EVERY, seed=len(drawn))
        drawn.append((turtle.x, turtle.y))
    batches = len(live.pen())
    assert batches >= hub.refresh_after - 1
    while hub.live_pen:                              # the flush of the next batch sends the refresh
        wander(sim, MARKER_EVERY, seed=len(drawn))
    pens = live.pen()
    assert pens and all(m['id'] >= mk.LAYER_ID_BASE for m in pens)
    assert np.array_equal(raster_of(pens), raster_keys(sim))
    for x, y in drawn[::50]:
        assert colour_at(pens, x, y) == (10, 20, 30)
    assert {m['ns'] for m in live.markers.values()} == {'bounds', 'robots', 'pen'}
    wander(sim, MARKER_EVERY, seed=1)
    assert [m['id'] for m in live.pen() if m['id'] < mk.LAYER_ID_BASE] in ([], [1])   # ids start over


@in_loop
def test_the_snapshot_is_built_when_a_viewer_joins():
    graph, hub, sim = station()
    calls = []
    hub.add_layer(lambda: calls.append(1) or [])
    wander(sim, 600)
    assert calls == []                                # drawing builds no snapshot
    late_snapshot(graph)
    late_snapshot(graph)
    assert calls == [1, 1]


@in_loop
def test_a_framed_station_keeps_its_frame_in_the_snapshot():
    graph, hub, sim = station(frame='turtlesim')
    teleport(sim, 3.0, 3.0)
    pens = pen_markers(late_snapshot(graph))
    assert pens and {m['header']['frame_id'] for m in pens} == {'turtlesim'}


def test_raster_boxes_runs_colours_and_budget():
    a = np.zeros((4, 40, 4), dtype=np.uint8)
    a[1, 1:4] = (255, 0, 0, 255)                      # a red run of 3 in row 1
    a[1, 4] = (0, 0, 255, 255)                        # then a blue pixel
    a[3, 0] = (255, 0, 0, 255)                        # a red pixel in the bottom-left corner
    a[2, 0:40] = (255, 0, 0, 255)                     # a red run of 40: boxes of 32 and 8
    ms = mk.raster_boxes(a, pixel=0.5, x0=1.0, y_top=10.0, ns='pen', id_base=100)
    boxes = {(m['color']['r'], m['color']['b'], round(m['scale']['x'] / 0.5 - mk.RASTER_OVERLAP)):
             [(p['x'], p['y']) for p in m['points']] for m in ms}
    assert boxes == {
        (1.0, 0.0, 3): [(2.0, 9.5)],                  # pixels 1..3 of row 1: x from 1.25 to 2.75
        (1.0, 0.0, 1): [(1.0, 8.5)],
        (1.0, 0.0, 32): [(8.75, 9.0)],
        (1.0, 0.0, 8): [(18.75, 9.0)],
        (0.0, 1.0, 1): [(3.0, 9.5)],
    }
    assert {m['id'] for m in ms} == set(range(100, 105)) and all(m['colors'] == [] for m in ms)
    assert all(m['scale']['y'] == 0.5 * (1 + mk.RASTER_OVERLAP) for m in ms)
    assert mk.raster_boxes(np.zeros((5, 5, 4), dtype=np.uint8), pixel=1, x0=0, y_top=0, ns='pen', id_base=0) == []
    # many colours: a marker per box size, a colour per box
    rainbow = np.zeros((PIXELS, PIXELS, 4), dtype=np.uint8)
    for i in range(100):
        rainbow[3 * i, 10:30 + i] = (i, 255 - i, 7, 255)
    ms = mk.raster_boxes(rainbow, pixel=1 / METER, x0=0, y_top=SIZE, ns='pen', id_base=0)
    assert len(ms) <= mk.RASTER_LONGEST and all(len(m['colors']) == len(m['points']) for m in ms)
    assert np.array_equal(raster_of(ms), np.where(rainbow[:, :, 3] > 0, (rainbow[:, :, 0].astype(np.int64) << 16)
                                                  | (rainbow[:, :, 1].astype(np.int64) << 8) | 7, -1))
    # noise: every pixel its own run and colour. The budget makes the cells coarser until it holds
    rng = np.random.default_rng(3)
    noise = np.zeros((PIXELS, PIXELS, 4), dtype=np.uint8)
    noise[:, :, :3] = rng.integers(0, 4, (PIXELS, PIXELS, 3)) * 60
    noise[:, :, 3] = 255
    ms = mk.raster_boxes(noise, pixel=1 / METER, x0=0, y_top=SIZE, ns='pen', id_base=0)
    assert len({m['scale']['y'] for m in ms}) == 1 and ms[0]['scale']['y'] > (1 + mk.RASTER_OVERLAP) / METER
    assert len(dumps({'markers': ms})) < mk.RASTER_BYTES * 1.1
