"""The outbox's cork: frames written while corked go out together, in order, in one write.

The outbox's own contract, with writers that record what they are given (the websocket side of
``write_many`` is checked through real clients in test_batched_frames.py and the rclpy suite).
"""

from __future__ import annotations

import asyncio

import pytest

from gateway.bridge.outbox import Outbox, corked

pytestmark = pytest.mark.asyncio


class Socket:
    """Records writes; each write's future completes when the test says the socket took it."""

    def __init__(self):
        self.writes: list[list[tuple[bytes, bool]]] = []
        self.futures: list[asyncio.Future] = []
        self.wrote = asyncio.Event()

    def _future(self) -> asyncio.Future:
        future = asyncio.get_running_loop().create_future()
        self.futures.append(future)
        return future

    def write(self, frame: bytes, binary: bool):
        return self.write_many([(frame, binary)])

    def write_many(self, frames):
        self.writes.append(list(frames))
        self.wrote.set()
        return self._future()

    async def until_writes(self, count: int, timeout: float = 5.0) -> list:
        """The writes once there are ``count`` of them (the outbox's pump task writes later)."""
        while len(self.writes) < count:
            self.wrote.clear()
            await asyncio.wait_for(self.wrote.wait(), timeout)
        return self.writes

    def drain(self) -> None:
        for future in self.futures:
            if not future.done():
                future.set_result(None)


def started(sock: Socket) -> Outbox:
    box = Outbox(sock.write, sock.write_many)
    box.start()
    return box


def opened() -> tuple[Socket, Outbox]:
    """A recording socket and a started outbox writing to it."""
    sock = Socket()
    return sock, started(sock)


async def test_frames_written_while_corked_go_out_in_one_write_in_order():
    sock, box = opened()
    with corked():
        box.message(b'm1', False, 'topic', 0)
        box.reply(b'status', False)
        box.message(b'm2', True, 'topic', 0)
        assert sock.writes == []
    assert sock.writes == [[(b'm1', False), (b'status', False), (b'm2', True)]]
    box.close()


async def test_without_a_cork_each_frame_is_written_at_once():
    sock, box = opened()
    box.message(b'm1', False, 'topic', 0)
    assert sock.writes == [[(b'm1', False)]]
    box.close()


async def test_every_outbox_written_under_one_cork_gets_its_own_single_write():
    a, b = Socket(), Socket()
    box_a, box_b = started(a), started(b)
    with corked():
        for i in range(3):
            box_a.message(b'a%d' % i, False, 'topic', 0)
            box_b.message(b'b%d' % i, False, 'topic', 0)
    assert a.writes == [[(b'a0', False), (b'a1', False), (b'a2', False)]]
    assert b.writes == [[(b'b0', False), (b'b1', False), (b'b2', False)]]
    box_a.close()
    box_b.close()


async def test_a_nested_cork_joins_the_outer_one():
    sock, box = opened()
    with corked():
        box.message(b'm1', False, 'topic', 0)
        with corked():
            box.message(b'm2', False, 'topic', 0)
        assert sock.writes == []
        box.message(b'm3', False, 'topic', 0)
    assert sock.writes == [[(b'm1', False), (b'm2', False), (b'm3', False)]]
    box.close()


async def test_while_a_write_is_pending_frames_queue_and_go_out_together_after_it():
    sock, box = opened()
    box.message(b'first', False, 'topic', 0)        # written at once; the socket has not taken it
    with corked():
        box.message(b'm1', False, 'topic', 0)
        box.reply(b'r1', False)
    box.message(b'm2', False, 'topic', 0)
    assert sock.writes == [[(b'first', False)]]     # the rest waits behind the pending write
    sock.drain()
    assert (await sock.until_writes(2))[1] == [(b'm1', False), (b'r1', False), (b'm2', False)]
    box.close()


async def test_a_queued_topic_message_beyond_its_queue_length_is_not_written():
    sock, box = opened()
    box.message(b'first', False, 'other', 0)
    for i in range(5):
        box.message(b'm%d' % i, False, 'topic', 2)   # queue_length 2: the two newest stay
    sock.drain()
    assert (await sock.until_writes(2))[1] == [(b'm3', False), (b'm4', False)]
    assert box.dropped == 3
    box.close()


async def test_an_outbox_closed_under_a_cork_writes_nothing():
    sock, box = opened()
    with corked():
        box.message(b'm1', False, 'topic', 0)
        box.close()
    assert sock.writes == []


async def test_frames_dropped_for_a_stalled_client_are_let_go_at_once():
    """A client that stopped reading: its socket never takes the first frame, and each newer
    frame of a newest-wins subscription replaces the waiting one. The replaced frames are
    released then, not kept in the queue until the pump reaches them (it never does)."""
    sock, box = opened()
    box.message(b'x' * 2**20, True, 'camera', 1)      # written; the socket never finishes it
    await sock.until_writes(1)
    for i in range(300):
        assert box.message(bytes([i % 256]) * 2**20, True, 'camera', 1)
    held = sum(len(e.frame) for e in box._queue)
    assert held == 2**20 and box.queued_bytes == 2**20   # the newest frame only
    assert len(box._queue) <= 130                        # the dropped ones' shells compacted
    assert box.dropped == 299
    sock.drain()
    writes = await sock.until_writes(2)
    assert writes[1] == [(bytes([299 % 256]) * 2**20, True)]   # the newest frame goes out next
    box.close()
