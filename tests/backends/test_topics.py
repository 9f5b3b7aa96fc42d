"""Publish/subscribe through the backend: round trips, bytes, NaN, latching, type checks."""

from __future__ import annotations

import asyncio
import math

import pytest

from gateway.backends.base import BackendError, QoS
from protocol.msgdefs import Definitions

from tests.support.contract import roundtrip, same
from tests.support.wait import until

pytestmark = pytest.mark.asyncio(loop_scope='session')


async def _roundtrip(world, topic, type, partial):
    backend = world.backend
    msg = world.full(type, partial)
    queue: asyncio.Queue = asyncio.Queue()
    sub = backend.subscribe(topic, type, queue.put_nowait)
    pub = backend.create_publisher(topic, type, QoS())
    try:
        got = await roundtrip(pub, queue, msg)
    finally:
        pub.destroy()
        sub.destroy()
    assert same(got, msg), (got, msg)
    return got


async def test_string(world, topic):
    got = await _roundtrip(world, topic, 'std_msgs/msg/String', {'data': 'héllo ✓'})
    assert got == {'data': 'héllo ✓'}


async def test_twist(world, topic):
    got = await _roundtrip(world, topic, 'geometry_msgs/msg/Twist',
                           {'linear': {'x': 1.5, 'y': -2.0}, 'angular': {'z': 0.25}})
    assert got['linear'] == {'x': 1.5, 'y': -2.0, 'z': 0.0}


async def test_image_bytes(world, topic):
    data = bytes(range(256)) * 12
    got = await _roundtrip(world, topic, 'sensor_msgs/msg/Image', {
        'header': {'stamp': {'sec': 12, 'nanosec': 345}, 'frame_id': 'cam'},
        'height': 48, 'width': 16, 'encoding': 'rgb8', 'step': 48, 'data': data})
    assert isinstance(got['data'], bytes) and got['data'] == data
    assert got['header']['stamp'] == {'sec': 12, 'nanosec': 345}


async def test_laserscan_nan(world, topic):
    ranges = [0.5, math.nan, math.inf, 1.25, -math.inf]
    got = await _roundtrip(world, topic, 'sensor_msgs/msg/LaserScan', {
        'angle_min': -1.5, 'angle_max': 1.5, 'range_max': 8.0, 'ranges': ranges,
        'intensities': [1.0, 2.0]})
    assert isinstance(got['ranges'], list) and math.isnan(got['ranges'][1])
    assert got['ranges'][2] == math.inf and got['ranges'][4] == -math.inf


async def test_latched_reaches_late_subscriber(world, topic):
    backend = world.backend
    pub = backend.create_publisher(topic, 'std_msgs/msg/String', QoS(depth=1, transient_local=True))
    pub.publish({'data': 'first'})
    pub.publish({'data': 'kept'})
    await until(lambda: backend.latched(topic), what='topic latched')
    queue: asyncio.Queue = asyncio.Queue()
    sub = backend.subscribe(topic, 'std_msgs/msg/String', queue.put_nowait)   # qos adapts
    try:
        assert await asyncio.wait_for(queue.get(), 5) == {'data': 'kept'}
    finally:
        sub.destroy()
        pub.destroy()


async def test_retained_never_arrives_after_a_newer_live_message(world, topic):
    """A message published right as a transient-local subscriber joins (before the backend had a
    chance to hand it the retained one) comes after the retained one, never before it."""
    backend = world.backend
    pub = backend.create_publisher(topic, 'std_msgs/msg/String', QoS(depth=1, transient_local=True))
    pub.publish({'data': '0'})
    await until(lambda: backend.latched(topic), what='topic latched')
    try:
        for n in range(1, 12, 2):
            got: list[int] = []
            sub = backend.subscribe(topic, 'std_msgs/msg/String', lambda m: got.append(int(m['data'])))
            pub.publish({'data': str(n)})   # no await in between: the subscription is a moment old
            try:
                await until(lambda: n in got, what=f'live message {n}')
                pub.publish({'data': str(n + 1)})   # a round trip: what came before it has arrived
                await until(lambda: n + 1 in got, what=f'live message {n + 1}')
                assert got == sorted(got) and set(got) <= {n - 1, n, n + 1}, got
            finally:
                sub.destroy()
    finally:
        pub.destroy()


async def test_volatile_not_replayed(world, topic):
    backend = world.backend
    pub = backend.create_publisher(topic, 'std_msgs/msg/String', QoS())
    pub.publish({'data': 'gone'})
    assert not backend.latched(topic)
    queue: asyncio.Queue = asyncio.Queue()
    sub = backend.subscribe(topic, 'std_msgs/msg/String', queue.put_nowait)
    try:
        got = await roundtrip(pub, queue, {'data': 'live'})
        assert got == {'data': 'live'}
    finally:
        sub.destroy()
        pub.destroy()


async def test_type_mismatch(world, topic):
    backend = world.backend
    pub = backend.create_publisher(topic, 'std_msgs/msg/String', QoS())
    try:
        with pytest.raises(BackendError, match='std_msgs/msg/String'):
            backend.create_publisher(topic, 'geometry_msgs/msg/Twist', QoS())
        with pytest.raises(BackendError):
            backend.subscribe(topic, 'geometry_msgs/msg/Twist', lambda msg: None)
        # the same type in the short spelling is no mismatch
        backend.create_publisher(topic, 'std_msgs/String', QoS()).destroy()
    finally:
        pub.destroy()


async def test_unknown_type(world, topic):
    with pytest.raises(LookupError):
        world.backend.create_publisher(topic, 'no_such_msgs/msg/Nothing', QoS())


async def test_talker(world):
    queue: asyncio.Queue = asyncio.Queue()
    sub = world.backend.subscribe('/chatter', 'std_msgs/msg/String', queue.put_nowait)
    try:
        msg = await asyncio.wait_for(queue.get(), 5)
    finally:
        sub.destroy()
    assert msg['data'].startswith('Hello World: ')


async def test_destroyed_subscription_gets_nothing(world, topic):
    backend = world.backend
    kept: asyncio.Queue = asyncio.Queue()
    dropped: list = []
    keep = backend.subscribe(topic, 'std_msgs/msg/String', kept.put_nowait)
    drop = backend.subscribe(topic, 'std_msgs/msg/String', dropped.append)
    pub = backend.create_publisher(topic, 'std_msgs/msg/String', QoS())
    try:
        await roundtrip(pub, kept, {'data': 'a'})
        await until(lambda: dropped, what='second subscription delivery')
        drop.destroy()
        dropped.clear()
        pub.publish({'data': 'b'})
        while (await asyncio.wait_for(kept.get(), 5)) != {'data': 'b'}:
            pass   # repeats of 'a' from the round trip
        assert dropped == []
    finally:
        pub.destroy()
        keep.destroy()


async def test_cdr_matches_rosbags(world):
    msg = world.full('geometry_msgs/msg/Twist', {'linear': {'x': 1.0}, 'angular': {'z': -0.5}})
    data = world.backend.to_cdr('geometry_msgs/msg/Twist', msg)
    defs = Definitions.jazzy()
    from protocol.convert import to_cdr
    assert data == to_cdr(defs, 'geometry_msgs/msg/Twist', msg)
    assert len(data) == 52 and data[:4] == b'\x00\x01\x00\x00'


async def test_the_cdr_as_received_is_kept_while_someone_wants_it(world, topic):
    """subscribe(cdr=True): JointState (string[]) has no compiled CDR reader on rclpy, so its
    messages are taken as objects (the cheaper take) until want_cdr(True), then as CDR."""
    backend, type = world.backend, 'sensor_msgs/msg/JointState'
    queue: asyncio.Queue = asyncio.Queue()
    sub = backend.subscribe(topic, type, lambda msg, cdr: queue.put_nowait((msg, cdr)), cdr=True)
    pub = backend.create_publisher(topic, type, QoS())

    async def one(name: str):
        while not queue.empty():
            queue.get_nowait()
        msg = world.full(type, {'name': [name, 'elbow'], 'position': [1.0, -0.5]})
        while True:
            got, cdr = await roundtrip(pub, queue, msg)
            if got['name'][0] == name:
                return got, cdr

    try:
        assert (await one('unwanted'))[1] is None
        sub.want_cdr(True)
        got, cdr = await one('wanted')
        if world.helpers is None:
            assert cdr is None        # the sim holds dicts: there is no CDR as received
        else:
            from rclpy.serialization import deserialize_message
            from sensor_msgs.msg import JointState
            assert isinstance(cdr, bytes) and cdr[:4] == b'\x00\x01\x00\x00'
            ros = deserialize_message(cdr, JointState)
            assert (list(ros.name), list(ros.position)) == (got['name'], got['position'])
        sub.want_cdr(False)
        assert (await one('unwanted again'))[1] is None
    finally:
        pub.destroy()
        sub.destroy()
