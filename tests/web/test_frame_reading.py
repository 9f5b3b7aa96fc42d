"""The gateway reads a connection's frames from a buffer it fills with whatever the socket holds
(server.TextAsBytesProtocol._read_bytes): frames of every RFC 6455 length encoding, an empty one
and a control frame among them must be read whole and in order, however the bytes arrive."""

from __future__ import annotations

import json

import pytest

from tests.support.rawclient import Raw

STRING = 'std_msgs/msg/String'
# frame payload lengths: 7-bit, its largest; 16-bit, its smallest and largest; 64-bit; several reads
PAYLOADS = [90, 125, 126, 65535, 65536, 300_000]


def publish_of_length(topic: str, index: int, length: int) -> str:
    """A publish op whose JSON text is exactly ``length`` bytes."""
    empty = json.dumps({'op': 'publish', 'topic': topic, 'msg': {'data': f'{index:03d}'}})
    return json.dumps({'op': 'publish', 'topic': topic, 'msg': {'data': f'{index:03d}'.ljust(3 + length - len(empty), 'x')}})


@pytest.mark.parametrize('piece', [None, 7, 4093], ids=['one write', '7 bytes a write', '4093 bytes a write'])
def test_frames_are_read_whole_and_in_order_however_the_bytes_arrive(gateway, piece):
    topic = f'/reading/bytes_{piece}'   # (a name part may not start with a digit: ROS 2's rule)
    ops = [publish_of_length(topic, i, n) for i, n in enumerate(PAYLOADS)]
    assert [len(op) for op in ops] == PAYLOADS
    with Raw(gateway.ws_url) as sub, Raw(gateway.ws_url) as pub:
        sub.send({'op': 'subscribe', 'topic': topic, 'type': STRING, 'queue_length': 100})
        sub.sync()
        pub.send({'op': 'advertise', 'topic': topic, 'type': STRING})
        pub.sync()
        protocol = pub.ws.protocol
        with pub.ws.send_context():
            for i, op in enumerate(ops):
                protocol.send_text(op.encode())
                if i == 2:
                    protocol.send_text(b'')        # an empty frame: a status, nothing else
                    protocol.send_ping(b'ping')    # a control frame between two messages
            wire = b''.join(protocol.data_to_send())
            step = piece or len(wire)
            for at in range(0, len(wire), step):
                pub.ws.socket.sendall(wire[at:at + step])
        assert pub.status()['level'] == 'error'
        pub.send('')     # an empty frame on its own: nothing follows its mask in the buffer
        assert pub.status()['level'] == 'error'
        pub.sync()
        got = [sub.expect(lambda m: m.get('op') == 'publish', timeout=30)['msg']['data'] for _ in ops]
    assert got == [json.loads(op)['msg']['data'] for op in ops]
    assert gateway.alive
