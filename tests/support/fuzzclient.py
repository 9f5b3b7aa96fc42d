"""A fuzzing connection: a reader thread keeps taking frames so the gateway never sees a stalled
client, and a barrier (a rosapi call) tells when everything sent before it was handled."""

from __future__ import annotations

import itertools
import json
import queue
import threading
import time

import cbor2
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

_barriers = itertools.count(1)


class Closed(Exception):
    def __init__(self, code: int | None, reason: str, last_status: dict | None = None):
        super().__init__(f'connection closed: {code} {reason}')
        self.code, self.reason = code, reason
        self.last_status = last_status   # the latest error or warning status before the close


class FuzzConn:
    def __init__(self, url: str):
        self.ws = connect(url, max_size=None, compression=None, open_timeout=10, legacy=True)
        self.inbox: queue.Queue = queue.Queue()
        self.code: int | None = None
        self.reason = ''
        self.last_status: dict | None = None   # the latest error or warning status since the last barrier
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        try:
            while True:
                frame = self.ws.recv()
                msg = cbor2.loads(frame) if isinstance(frame, bytes) else json.loads(frame)
                if msg.get('op') == 'status' and msg.get('level') in ('error', 'warning'):
                    self.last_status = msg
                elif msg.get('op') == 'service_response' and str(msg.get('id')).startswith('barrier-'):
                    self.last_status = None
                self.inbox.put(msg)
        except ConnectionClosed as e:
            # no close frame from the server: 1006, the connection was dropped
            self.code, self.reason = (e.rcvd.code, e.rcvd.reason) if e.rcvd else (1006, '')
        finally:
            self.inbox.put(None)

    @property
    def closed(self) -> bool:
        return not self.thread.is_alive()

    def send(self, payload: str | bytes, text: bool | None = None) -> None:
        try:
            self.ws.send(payload, text=text)
        except ConnectionClosed:
            self.thread.join(10)
            raise Closed(self.code, self.reason, self.last_status) from None

    def barrier(self, timeout: float = 60.0) -> list[dict]:
        """Everything received until the reply to a fresh rosapi call (sent now)."""
        id = f'barrier-{next(_barriers)}'
        self.send(json.dumps({'op': 'call_service', 'service': '/rosapi/get_time', 'id': id}))
        got: list[dict] = []
        deadline = time.monotonic() + timeout
        while True:
            try:
                msg = self.inbox.get(timeout=max(0.01, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError(f'no reply to {id} within {timeout} s') from None
            if msg is None:
                raise Closed(self.code, self.reason, self.last_status)
            if msg.get('id') == id and msg.get('op') == 'service_response':
                return got
            got.append(msg)

    def close(self) -> None:
        self.ws.close()
        self.thread.join(10)
