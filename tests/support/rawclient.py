"""A minimal rosbridge client over raw websocket frames, for tests that need exact control."""

from __future__ import annotations

import json
import time

import cbor2
from websockets.sync.client import connect

from tests.support.wait import TIMEOUT


class Raw:
    def __init__(self, url: str, **kw):
        self.ws = connect(url, max_size=None, compression=None, open_timeout=TIMEOUT, legacy=True, **kw)
        self.seen: list[dict] = []

    def send(self, op) -> None:
        if isinstance(op, dict):
            op = json.dumps(op)
        self.ws.send(op)

    def send_together(self, *ops) -> None:
        """Several ops in one TCP write, so the gateway reads and handles them in one go."""
        with self.ws.send_context():
            for op in ops:
                self.ws.protocol.send_text((op if isinstance(op, str) else json.dumps(op)).encode())
            self.ws.socket.sendall(b''.join(self.ws.protocol.data_to_send()))

    def recv(self, timeout: float = TIMEOUT) -> dict:
        frame = self.ws.recv(timeout=timeout)
        if isinstance(frame, bytes):
            return cbor2.loads(frame)
        return json.loads(frame)

    def incoming(self, stopped):
        """Messages as they arrive until stopped() is true, for a reader thread: a receive that times
        out (every 0.2 s, to look at stopped()) or fails is passed over."""
        while not stopped():
            try:
                yield self.recv(0.2)
            except Exception:
                continue

    def expect(self, predicate, timeout: float = TIMEOUT) -> dict:
        """The first message matching predicate; everything read before it lands in self.seen."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f'no matching message within {timeout} s; saw {self.seen[-5:]}')
            try:
                msg = self.recv(left)
            except TimeoutError:
                continue
            if predicate(msg):
                return msg
            self.seen.append(msg)

    def status(self, id=None, timeout: float = TIMEOUT) -> dict:
        return self.expect(lambda m: m.get('op') == 'status' and (id is None or m.get('id') == id), timeout)

    def call(self, service: str, args: dict | None = None, timeout: float = TIMEOUT) -> dict:
        self._calls = getattr(self, '_calls', 0) + 1
        id = f'raw-call-{self._calls}'
        self.send({'op': 'call_service', 'id': id, 'service': service, 'args': args or {}})
        return self.expect(lambda m: m.get('id') == id, timeout)

    def sync(self) -> None:
        """A round trip: every op this client sent before has been handled."""
        self.call('/rosapi/get_time')

    def wait_listed(self, service: str, field: str, name: str, timeout: float = TIMEOUT) -> None:
        """Until a rosapi listing (e.g. '/rosapi/services', 'services') shows name."""
        deadline = time.monotonic() + timeout
        while name not in self.call(service)['values'][field]:
            if time.monotonic() > deadline:
                raise AssertionError(f'{name} never appeared in {service}')
            time.sleep(0.01)

    def close(self) -> None:
        self.ws.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
