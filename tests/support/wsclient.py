"""A raw rosbridge client with the small conveniences the security tests need."""

from __future__ import annotations

import itertools
import time
from urllib.parse import quote

from websockets.exceptions import ConnectionClosed

from tests.support.rawclient import Raw
from tests.support.wait import TIMEOUT

TWIST = 'geometry_msgs/msg/Twist'
TWIST_STAMPED = 'geometry_msgs/msg/TwistStamped'


def with_token(url: str, token: str | None) -> str:
    return url if token is None else f'{url}?token={quote(token)}'


def twist(x=0.0, y=0.0, z=0.0, az=0.0) -> dict:
    return {'linear': {'x': x, 'y': y, 'z': z}, 'angular': {'x': 0.0, 'y': 0.0, 'z': az}}


def is_zero_twist(msg: dict) -> bool:
    body = msg.get('twist', msg)
    return all(v == 0 for part in ('linear', 'angular') for v in body[part].values())


class Client(Raw):
    def __init__(self, url: str, token: str | None = None, **kw):
        super().__init__(with_token(url, token), **kw)
        self._ids = itertools.count(1)

    def expect(self, predicate, timeout: float = TIMEOUT) -> dict:
        """As Raw.expect, but messages skipped earlier (self.seen) are looked at first."""
        for i, msg in enumerate(self.seen):
            if predicate(msg):
                return self.seen.pop(i)
        return super().expect(predicate, timeout)

    def next_id(self, prefix: str) -> str:
        return f'{prefix}:{next(self._ids)}'

    def ask(self, op: dict, timeout: float = TIMEOUT) -> list[dict]:
        """Send op (a fresh id unless given), then a rosapi call as a barrier; everything that
        came back for op's id before the barrier's reply. Refused ops answer synchronously, so a
        refusal is always in there; the barrier call is answered even when it is refused."""
        op.setdefault('id', self.next_id(op['op']))
        self.send(op)
        barrier = self.next_id('barrier')
        self.send({'op': 'call_service', 'service': '/rosapi/get_time', 'id': barrier})
        got = []

        def barrier_reply(m: dict) -> bool:
            if m.get('id') == op['id']:
                got.append(m)
            return m.get('id') == barrier

        self.expect(barrier_reply, timeout)
        return got

    def refusal(self, op: dict) -> dict | None:
        """The status error op got (None when it was accepted)."""
        errors = [m for m in self.ask(op) if m.get('op') == 'status' and m.get('level') == 'error']
        return errors[0] if errors else None

    def call(self, service: str, args: dict | None = None, timeout: float = TIMEOUT, **kw) -> dict:
        id = self.next_id(f'call_service:{service}')
        self.send({'op': 'call_service', 'service': service, 'args': args or {}, 'id': id, **kw})
        return self.expect(lambda m: m.get('op') == 'service_response' and m.get('id') == id, timeout)

    def subscribe(self, topic: str, type: str, **kw) -> None:
        assert self.refusal({'op': 'subscribe', 'topic': topic, 'type': type, **kw}) is None

    def publish(self, topic: str, msg: dict, type: str | None = None, id: str | None = None) -> None:
        op = {'op': 'publish', 'topic': topic, 'msg': msg, 'id': id or self.next_id(f'publish:{topic}')}
        if type:
            op['type'] = type
        self.send(op)

    def next_message(self, topic: str, predicate=lambda msg: True, timeout: float = TIMEOUT) -> dict:
        return self.expect(lambda m: m.get('op') == 'publish' and m.get('topic') == topic
                           and predicate(m['msg']), timeout)['msg']

    def closed_code(self, timeout: float = TIMEOUT) -> int | None:
        """Read (into self.seen) until the server closes the connection; its close code."""
        deadline = time.monotonic() + timeout
        try:
            while time.monotonic() < deadline:
                try:
                    self.seen.append(self.recv(max(0.01, deadline - time.monotonic())))
                except TimeoutError:
                    pass
        except ConnectionClosed as e:
            return e.rcvd.code if e.rcvd else None
        raise AssertionError(f'the server did not close the connection within {timeout} s')
