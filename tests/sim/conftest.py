"""Gateways with simulated robots, driven through the websocket by roslibpy."""

from __future__ import annotations

import json

import pytest

# A small rover world: a box whose near face is 1.5 m ahead of the start.
WALL_WORLD = {
    'name': 'walltest', 'size': [6.0, 4.0], 'start': [1.0, 2.0, 0.0],
    'boxes': [{'center': [2.75, 2.0], 'size': [0.5, 1.2], 'color': [0.8, 0.2, 0.2]}],
}


@pytest.fixture(scope='module')
def turtle_gw(start_gateway):
    gw = start_gateway('--robot', 'turtlesim')
    yield gw
    gw.stop()


@pytest.fixture(scope='module')
def rover_gw(start_gateway, tmp_path_factory):
    path = tmp_path_factory.mktemp('worlds') / 'walltest.json'
    path.write_text(json.dumps(WALL_WORLD))
    gw = start_gateway('--robot', 'rover', '--world', str(path))
    yield gw
    gw.stop()


@pytest.fixture(scope='module')
def fleet_gw(start_gateway):
    gw = start_gateway('--fleet', '3', '--robot', 'turtlesim', '--robot', 'rover', '--world', 'maze',
                       '--twist-stamped', '--sim-speed', '2')
    yield gw
    gw.stop()
