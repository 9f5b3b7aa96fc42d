"""On rclpy the loop takes what the gateway published itself from its own readers, and the pump
stops waiting on those readers while the gateway keeps publishing (``RclpyBackend.published``).

These check the hand-overs between the two with real rclpy: a ROS node's messages still arrive
once the gateway stops publishing, and a topic whose take comes up short goes back to the pump.
"""

from __future__ import annotations

import asyncio

import pytest

from gateway.backends.base import QoS

from tests.support.contract import rclpy_missing, roundtrip
from tests.support.wait import until

pytestmark = [
    pytest.mark.asyncio(loop_scope='session'),
    pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here'),
]
STRING = 'std_msgs/msg/String'


@pytest.fixture
def rclpy_world(world):
    if world.helpers is None:
        pytest.skip('the loop and pump hand-over is the rclpy backend\'s')
    return world


async def received(queue: asyncio.Queue, count: int, timeout: float = 10.0) -> list[str]:
    """The data of the next ``count`` messages that are not warm-ups."""
    got: list[str] = []
    while len(got) < count:
        data = (await asyncio.wait_for(queue.get(), timeout))['data']
        if data != 'warm-up':
            got.append(data)
    return got


async def from_node(publish, queue: asyncio.Queue, timeout: float = 20.0) -> None:
    """Publish from the ROS node until the gateway's subscription delivers one of its messages."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while True:
        assert loop.time() < deadline, 'no message of the ROS node arrived'
        publish('from the node')
        try:
            while (await asyncio.wait_for(queue.get(), 0.2))['data'] != 'from the node':
                pass
            return
        except asyncio.TimeoutError:
            continue


async def test_a_ros_node_is_heard_again_once_the_gateway_stops_publishing(rclpy_world, caller, topic):
    backend = rclpy_world.backend
    queue: asyncio.Queue = asyncio.Queue()
    sub = backend.subscribe(topic, STRING, queue.put_nowait)
    pub = backend.create_publisher(topic, STRING, QoS())
    try:
        await roundtrip(pub, queue, {'data': 'warm-up'})
        for i in range(100):               # one round of the loop: taken every 32 and at its end
            pub.publish({'data': str(i)})
        assert topic in backend._held      # the loop takes this topic's messages itself
        assert await received(queue, 100) == [str(i) for i in range(100)]
        await until(lambda: topic not in backend._held, what='the topic handed back to the pump')
        publish, _count = caller.string_publisher(topic)
        await from_node(publish, queue)    # only the pump takes it now
    finally:
        sub.destroy()
        pub.destroy()


async def test_a_topic_whose_take_comes_up_short_goes_back_to_the_pump(rclpy_world, topic):
    """A reader that holds one message misses two of three published in one round, as a
    middleware that delivers after the publish call returns would: the pump takes that topic."""
    backend = rclpy_world.backend
    queue: asyncio.Queue = asyncio.Queue()
    sub = backend.subscribe(topic, STRING, queue.put_nowait, QoS(depth=1))
    pub = backend.create_publisher(topic, STRING, QoS())
    try:
        await roundtrip(pub, queue, {'data': 'warm-up'})
        for i in range(3):
            pub.publish({'data': f'lost {i}'})
        await until(lambda: topic not in backend._held and topic in backend._unheld,
                    what='the topic left to the pump')
        while not queue.empty():
            queue.get_nowait()
        for i in range(5):    # one at a time: depth 1 keeps each
            pub.publish({'data': str(i)})
            assert await received(queue, 1) == [str(i)]
        assert topic not in backend._held
    finally:
        sub.destroy()
        pub.destroy()
