"""The Foxglove message data frames of one message: its receive time read once for every
subscriber, one frame per subscription id (clients that chose the same id share it), the next
message read anew."""

from __future__ import annotations

import struct

from gateway.bridge.foxglove.hub import Framer


def test_one_time_per_message_and_one_frame_per_subscription_id():
    ticks = iter([(7, 5), (8, 0)])
    framer = Framer(lambda: next(ticks))
    payload = b'\x00\x01\x00\x00' + bytes(100)
    first = framer.frame(0, payload)
    assert first[:13] == struct.pack('<BIQ', 1, 0, 7_000_000_005) and first[13:] == payload
    assert framer.frame(0, payload) is first                 # another client with id 0: the same frame
    other = framer.frame(3, payload)
    assert other[:13] == struct.pack('<BIQ', 1, 3, 7_000_000_005) and other[13:] == payload
    following = payload[:4] + payload[4:]                    # the next message: equal bytes, another object
    later = framer.frame(0, following)
    assert later is not first and later[:13] == struct.pack('<BIQ', 1, 0, 8_000_000_000)
