"""A Foxglove WebSocket protocol client for the Python tests and benches: JSON ops and binary
frames by hand, over the websockets package (the Node tests use npm's FoxgloveClient itself)."""

from __future__ import annotations

import json
import struct
import time
from urllib.parse import quote

from websockets.sync.client import connect

SUBPROTOCOL = 'foxglove.websocket.v1'
CDR_HEADER = b'\x00\x01\x00\x00'   # little-endian CDR, as rmw writes it


def twist_cdr(x: float = 0.0, z: float = 0.0) -> bytes:
    """geometry_msgs/msg/Twist as CDR: six float64, linear then angular."""
    return CDR_HEADER + struct.pack('<6d', x, 0.0, 0.0, 0.0, 0.0, z)


def read_twist(cdr: bytes) -> tuple[float, float]:
    """(linear.x, angular.z) of a Twist's CDR."""
    values = struct.unpack_from('<6d', cdr, 4)
    return values[0], values[5]


def read_pose(cdr: bytes) -> tuple[float, float, float]:
    """(x, y, theta) of a turtlesim/msg/Pose's CDR."""
    return struct.unpack_from('<3f', cdr, 4)


class Fox:
    """One connection. ``expect(predicate)`` reads until a message matches (JSON ops as dicts,
    message data as ('message', subscription id, timestamp, payload), service responses as
    ('response', service id, call id, payload)); what it reads on the way is kept in ``seen``."""

    def __init__(self, url: str, token: str | None = None, subprotocols=(SUBPROTOCOL,), **kw):
        if token is not None:
            url = f'{url}?token={quote(token)}'
        self.ws = connect(url, subprotocols=list(subprotocols), max_size=None, compression=None,
                          open_timeout=10, legacy=True, **kw)
        self.seen: list = []
        self.channels: dict[str, dict] = {}
        self.services: dict[str, dict] = {}
        self._ids = iter(range(1, 2**31))

    @property
    def subprotocol(self):
        return self.ws.subprotocol

    def close(self) -> None:
        self.ws.close()

    def send(self, op: dict) -> None:
        self.ws.send(json.dumps(op))

    def recv(self, timeout: float = 10.0):
        frame = self.ws.recv(timeout=timeout)
        if isinstance(frame, str):
            msg = json.loads(frame)
            if msg.get('op') == 'advertise':
                self.channels.update((c['topic'], c) for c in msg['channels'])
            elif msg.get('op') == 'unadvertise':
                self.channels = {t: c for t, c in self.channels.items() if c['id'] not in msg['channelIds']}
            elif msg.get('op') == 'advertiseServices':
                self.services.update((s['name'], s) for s in msg['services'])
            return msg
        if frame[0] == 0x01:
            sub, stamp = struct.unpack_from('<IQ', frame, 1)
            return ('message', sub, stamp, frame[13:])
        if frame[0] == 0x03:
            service, call, size = struct.unpack_from('<III', frame, 1)
            return ('response', service, call, frame[13 + size:])
        return ('binary', frame)

    def expect(self, predicate, timeout: float = 10.0):
        for i, msg in enumerate(self.seen):
            if predicate(msg):
                return self.seen.pop(i)
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f'no matching message within {timeout} s; saw {self.seen[-5:]}')
            msg = self.recv(left)
            if predicate(msg):
                return msg
            self.seen.append(msg)

    def status(self, needle: str, timeout: float = 10.0) -> dict:
        return self.expect(lambda m: isinstance(m, dict) and m.get('op') == 'status' and needle in m['message'],
                           timeout)

    def channel(self, topic: str, timeout: float = 10.0) -> dict:
        if topic not in self.channels:
            self.expect(lambda m: topic in self.channels, timeout)
        return self.channels[topic]

    def subscribe(self, topic: str) -> int:
        sid = next(self._ids)
        self.send({'op': 'subscribe', 'subscriptions': [{'id': sid, 'channelId': self.channel(topic)['id']}]})
        return sid

    def message(self, sid: int, timeout: float = 10.0) -> bytes:
        return self.expect(lambda m: isinstance(m, tuple) and m[0] == 'message' and m[1] == sid, timeout)[3]

    def advertise(self, topic: str, schema: str, encoding: str = 'cdr') -> int:
        cid = next(self._ids)
        self.send({'op': 'advertise', 'channels': [{'id': cid, 'topic': topic, 'encoding': encoding,
                                                    'schemaName': schema}]})
        return cid

    def publish(self, channel: int, payload: bytes) -> None:
        self.ws.send(b'\x01' + struct.pack('<I', channel) + payload)

    def call(self, name: str, payload: bytes, encoding: str = 'cdr', timeout: float = 10.0):
        """A service call: ('response', ...) or the serviceCallFailure op."""
        service = self.services.get(name) or self.expect(lambda m: name in self.services, timeout) and self.services[name]
        call = next(self._ids)
        enc = encoding.encode()
        self.ws.send(b'\x02' + struct.pack('<III', service['id'], call, len(enc)) + enc + payload)
        return self.expect(lambda m: (isinstance(m, tuple) and m[0] == 'response' and m[2] == call)
                           or (isinstance(m, dict) and m.get('op') == 'serviceCallFailure' and m['callId'] == call),
                           timeout)
