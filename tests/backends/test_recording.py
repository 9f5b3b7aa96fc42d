"""Recording and playback on every backend: what a publisher sends is in the MCAP bag, in order,
and playing the bag publishes it again."""

from __future__ import annotations

import asyncio
import contextlib

import pytest

from gateway.backends.base import QoS
from gateway.bridge.gateway import Gateway
from gateway.bridge.taps import Senders, Taps
from gateway.media.recordings import RecordingLimits, RecordingManager
from gateway.rules.errors import Refusal
from gateway.settings import Settings

from tests.support.wait import until

pytestmark = pytest.mark.asyncio(loop_scope='session')
STRING = 'std_msgs/msg/String'


def recordings(gateway: Gateway, folder, limits: RecordingLimits = RecordingLimits()) -> RecordingManager:
    """A manager handed its doors as the server's start hands them."""
    return RecordingManager(folder, limits, taps=Taps(gateway), types=gateway.backend, graph=gateway.backend,
                            senders=Senders(gateway), names=gateway.policy)


async def test_record_then_play(world, topic, tmp_path):
    from rosbags.highlevel import AnyReader

    backend = world.backend
    gateway = Gateway(Settings(), backend)
    manager = recordings(gateway, tmp_path)
    pub = backend.create_publisher(topic, STRING, QoS())
    try:
        await until(lambda: any(name == topic for name, _ in backend.topics()), what=f'{topic} in the graph')
        rec = manager.start((topic,), None)
        assert list(rec.connections) == [topic]
        sent = 0   # recorded: the warm-up messages (at least one), then these
        deadline = asyncio.get_running_loop().time() + 10
        while rec.messages == 0:   # a fresh ROS subscription may need a moment to match
            assert asyncio.get_running_loop().time() < deadline, 'the recording never got a message'
            pub.publish({'data': 'warm-up'})
            with contextlib.suppress(AssertionError):
                await until(lambda: rec.messages > 0, timeout=0.1, what='a warm-up message recorded')
        for i in range(50):   # lock-step: each one recorded before the next is sent
            base = rec.messages
            pub.publish({'data': f'message {i}'})
            sent += 1
            await until(lambda: rec.messages > base, what=f'message {i} recorded')
        manager.stop(rec, 'done')
    finally:
        pub.destroy()
    assert rec.state == 'done' and rec.taps == {}
    with AnyReader([rec.path]) as reader:
        rows = [(c.topic, c.msgtype, stamp, reader.deserialize(raw, c.msgtype).data)
                for c, stamp, raw in reader.messages()]
    texts = [r[3] for r in rows if r[3] != 'warm-up']
    assert texts == [f'message {i}' for i in range(50)]
    assert {(r[0], r[1]) for r in rows} == {(topic, STRING)}
    assert all(b[2] > a[2] for a, b in zip(rows, rows[1:]))

    got: asyncio.Queue = asyncio.Queue()
    sub = backend.subscribe('/replay' + topic, STRING, got.put_nowait)
    try:
        info = manager.play(rec.id, 1.0, '/replay')
        assert info['messages'] == len(rows)
        await manager.plays[rec.id]
        received = []
        while 'message 49' not in received:   # the last messages may still be on their way
            received.append((await asyncio.wait_for(got.get(), 5))['data'])
    finally:
        sub.destroy()
    # over DDS the player's new publisher may match the subscription after its first messages
    played = [t for t in received if t != 'warm-up']
    expected = [f'message {i}' for i in range(50)]
    assert played == expected[len(expected) - len(played):]
    assert len(played) >= (50 if backend.name == 'sim' else 10), played


async def test_bounds(world, topic, tmp_path):
    backend = world.backend
    gateway = Gateway(Settings(), backend)
    pub = backend.create_publisher(topic, STRING, QoS())
    try:
        await until(lambda: any(name == topic for name, _ in backend.topics()), what=f'{topic} in the graph')
        full = recordings(gateway, tmp_path, RecordingLimits(disk_reserve=2**62))
        with pytest.raises(Refusal) as refused:
            full.start((topic,), None)
        assert refused.value.status == 507 and 'free' in refused.value.message

        small = recordings(gateway, tmp_path, RecordingLimits(max_bytes=2000, max_concurrent=1))
        rec = small.start((topic,), None)
        with pytest.raises(Refusal) as busy:
            small.start((topic,), None)
        assert busy.value.status == 409
        while rec.state == 'recording':   # lock-step: each message recorded, or the cap reached
            base = rec.messages
            pub.publish({'data': 'x' * 100})
            await until(lambda: rec.messages > base or rec.state != 'recording',
                        what='a message recorded or the size cap reached')
    finally:
        pub.destroy()
    assert rec.state == 'done' and 'size cap' in rec.reason
    assert rec.messages * 100 < 2000 and rec.file.stat().st_size < 2000 + 4096
