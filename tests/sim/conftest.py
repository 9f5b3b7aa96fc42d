"""Gateways with simulated robots, driven through the websocket by roslibpy."""

from __future__ import annotations

import json
import threading
import time

import pytest
import roslibpy

from tests.conftest import client, wait_for  # noqa: F401 (client: used by the sim tests)

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


class Inbox:
    """Messages of one topic with their arrival times (monotonic)."""

    def __init__(self, ros, topic: str, type: str, **kwargs):
        self.items: list[tuple[float, dict]] = []
        self.lock = threading.Lock()
        self.topic = roslibpy.Topic(ros, topic, type, **kwargs)
        self.topic.subscribe(self._add)

    def _add(self, msg: dict) -> None:
        with self.lock:
            self.items.append((time.monotonic(), msg))

    @property
    def messages(self) -> list[dict]:
        with self.lock:
            return [m for _, m in self.items]

    @property
    def last(self) -> dict | None:
        with self.lock:
            return self.items[-1][1] if self.items else None

    def since(self, t: float) -> list[dict]:
        with self.lock:
            return [m for at, m in self.items if at >= t]

    def wait(self, predicate=lambda m: True, timeout: float = 5.0, after: float = 0.0) -> dict:
        """The first message (arrived after ``after``) that satisfies predicate."""
        def found():
            return next((m for m in self.since(after) if predicate(m)), None)
        return wait_for(found, timeout)

    def close(self) -> None:
        self.topic.unsubscribe()


def call(ros, name: str, type: str, request: dict | None = None, timeout: float = 5.0) -> dict:
    return roslibpy.Service(ros, name, type).call(roslibpy.ServiceRequest(request or {}), timeout=timeout)


def twist(x: float = 0.0, z: float = 0.0) -> dict:
    return {'linear': {'x': x, 'y': 0.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': z}}


def stream(pub: roslibpy.Topic, msg: dict, seconds: float, rate: float = 20.0) -> float:
    """Publish msg at rate for seconds; the time of the last publish."""
    start = time.monotonic()
    last = start
    while time.monotonic() - start < seconds:
        pub.publish(roslibpy.Message(msg))
        last = time.monotonic()
        time.sleep(1 / rate)
    return last
