"""Frames that wait in a client's queue go out several to a socket write, built by the gateway
itself (server.RosbridgeHandler._send_many): every length encoding of RFC 6455 (7-bit, 16-bit,
64-bit), text and binary, must reach a real client intact and in order."""

from __future__ import annotations

import pytest

from tests.support.rawclient import Raw

STRING = 'std_msgs/msg/String'
# one of each length encoding per round: 7-bit (< 126), 16-bit, 64-bit (> 65535)
SIZES = [3, 125, 126, 300, 65535, 65536, 1_000_000]
ROUNDS = 12   # about 13 MB: more than loopback's socket buffers hold, so frames queue


@pytest.mark.parametrize('compression', ['none', 'cbor'])
def test_queued_frames_of_every_size_arrive_intact_and_in_order(gateway, compression):
    topic = f'/batched/{compression}'
    expected = [f'{r:02d}{i}'.ljust(size, 'x') for r in range(ROUNDS) for i, size in enumerate(SIZES)]
    with Raw(gateway.ws_url) as sub, Raw(gateway.ws_url) as pub:
        sub.send({'op': 'subscribe', 'topic': topic, 'type': STRING, 'compression': compression,
                  'queue_length': len(expected)})
        sub.sync()
        pub.send({'op': 'advertise', 'topic': topic, 'type': STRING})
        for data in expected:
            pub.send({'op': 'publish', 'topic': topic, 'msg': {'data': data}})
        pub.sync()   # all published: the subscriber's frames are written or queued by now
        got = [sub.expect(lambda m: m.get('op') == 'publish', timeout=30)['msg']['data']
               for _ in expected]
    assert [len(d) for d in got] == [len(d) for d in expected]
    assert got == expected
    assert gateway.alive
