"""Playing a recording back into the graph: each message on its topic (under an optional prefix)
at its recorded time offset divided by ``rate``.

Messages are decoded with the definitions stored in the bag itself (not the backend's), so a
recording plays on any backend that knows the types' names.
"""

from __future__ import annotations

import asyncio
import logging
from pathlib import Path

from protocol.convert import from_cdr
from protocol.msgdefs import Definitions

from .backends.base import QoS

log = logging.getLogger('rosgate.recordings')


class Playback:
    def __init__(self, backend, path: Path, rate: float, prefix: str):
        from rosbags.rosbag2 import Reader

        self.backend, self.path, self.rate, self.prefix = backend, path, rate, prefix
        self.reader = Reader(path)
        self.reader.open()
        self.defs = _definitions(self.reader)
        self.published = 0

    def summary(self) -> dict:
        r = self.reader
        return {'id': self.path.name, 'rate': self.rate, 'prefix': self.prefix, 'messages': r.message_count,
                'duration': (r.end_time - r.start_time) / 1e9 if r.message_count else 0.0,
                'topics': sorted(self.prefix + c.topic for c in r.connections)}

    async def run(self) -> int:
        loop = asyncio.get_running_loop()
        pubs = {}
        try:
            for conn in self.reader.connections:
                pubs[conn.id] = self.backend.create_publisher(self.prefix + conn.topic, conn.msgtype, QoS())
            t0, start = None, loop.time()
            for conn, stamp, data in self.reader.messages():
                if t0 is None:
                    t0 = stamp
                delay = start + (stamp - t0) / 1e9 / self.rate - loop.time()
                if delay > 0:
                    await asyncio.sleep(delay)
                pubs[conn.id].publish(from_cdr(self.defs, conn.msgtype, bytes(data)))
                self.published += 1
            log.info('played %s: %d messages', self.path.name, self.published)
            return self.published
        finally:
            for pub in pubs.values():
                pub.destroy()
            self.reader.close()


def _definitions(reader) -> Definitions:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    for conn in reader.connections:
        store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
    defs = Definitions()
    defs.load_typestore(store)
    return defs
