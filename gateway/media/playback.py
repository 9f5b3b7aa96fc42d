"""Playing a recording back into the graph: each message on its topic (under an optional prefix)
at its recorded time offset divided by ``rate``.

A playback publishes for the person who started it, through the gateway's one door (``Senders``): the name
globs, the driver lease, clamps and stops apply as to that person's own ``publish`` ops. When
a rule refuses a message (someone else drives that robot, an admin stopped it) the playback ends.

Messages are decoded with the definitions stored in the bag itself (not the backend's), so a
recording plays on any backend that knows the types' names.
"""

from __future__ import annotations

import asyncio
import logging
from pathlib import Path

from protocol.convert import from_cdr
from protocol.errors import ProtocolError
from protocol.msgdefs import Definitions

from ..backends.base import QoS
from .ports import Senders

log = logging.getLogger('rosgate.recordings')


class Playback:
    def __init__(self, senders: Senders, path: Path, rate: float, prefix: str, name: str, role: str | None,
                 person: str | None = None):
        from rosbags.rosbag2 import Reader

        self.senders, self.path, self.rate, self.prefix = senders, path, rate, prefix
        self.who = (name, role, person)   # person: rules.stations.person_of of who started it
        self.reader = Reader(path)
        self.reader.open()
        self.defs = _definitions(self.reader)
        self.published = 0
        self.refused: str | None = None   # why a rule ended the playback

    def summary(self) -> dict:
        r = self.reader
        return {'id': self.path.name, 'rate': self.rate, 'prefix': self.prefix, 'messages': r.message_count,
                'duration': (r.end_time - r.start_time) / 1e9 if r.message_count else 0.0,
                'topics': sorted(topic for topic, _ in self.targets())}

    def targets(self) -> list[tuple[str, str]]:
        """(topic, type) of each topic the playback publishes on."""
        return [(self.prefix + c.topic, c.msgtype) for c in self.reader.connections]

    async def run(self) -> int:
        loop = asyncio.get_running_loop()
        door = self.senders
        name, role, person = self.who
        sender = door.open_sender(name, role, remote=f'playback of {self.path.name}', person=person)
        pubs = {}
        try:
            for conn in self.reader.connections:
                pubs[conn.id] = door.open_publisher(sender, self.prefix + conn.topic, conn.msgtype, QoS())
            t0, start = None, loop.time()
            for conn, stamp, data in self.reader.messages():
                if t0 is None:
                    t0 = stamp
                delay = start + (stamp - t0) / 1e9 / self.rate - loop.time()
                if delay > 0:
                    await asyncio.sleep(delay)
                if door.publish(sender, pubs[conn.id], from_cdr(self.defs, conn.msgtype, bytes(data))):
                    self.published += 1
            log.info('played %s: %d messages', self.path.name, self.published)
        except ProtocolError as e:
            self.refused = e.message
            log.info('playing %s ended after %d messages: %s', self.path.name, self.published, e.message)
        finally:
            door.close_sender(sender)   # its moving commands stop, its leases go
            for pub in pubs.values():
                pub.detach(sender.id)
            self.reader.close()
        return self.published


def _definitions(reader) -> Definitions:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    for conn in reader.connections:
        store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
    defs = Definitions()
    defs.load_typestore(store)
    return defs
