"""A TCP relay between one gateway and the test's PostgreSQL (tests/support/postgres.py), to make the
database unreachable for that gateway alone, as a network that drops everything does:

    relay = Relay(pg.port)                 # 127.0.0.1:relay.port -> 127.0.0.1:pg.port
    gw = start(..., '--db', relay.url(pg.url))
    back = relay.cut(10.0)                 # for 10 s nothing passes either way

While cut, nothing is read or forwarded (statements wait, as on a dead link), and a new connection
is accepted but never reaches the server (its client's connect timeout ends it). When the cut ends,
every connection that lived through it is dropped (both ends' TCP would have given up on a link dead
that long) and new ones pass again. One thread, select(); stopped with ``close()``.
"""

from __future__ import annotations

import selectors
import socket
import threading
import time


class Relay:
    def __init__(self, upstream_port: int, host: str = '127.0.0.1'):
        self.upstream = (host, upstream_port)
        self.listener = socket.create_server((host, 0))
        self.listener.setblocking(False)
        self.port = self.listener.getsockname()[1]
        self.until = 0.0                      # time.monotonic() the cut ends
        self.pairs: dict[socket.socket, socket.socket | None] = {}
        self.held: set[socket.socket] = set()     # connections that lived through a cut
        self.closed = False
        self.cuts = 0
        self._seen_cut = threading.Event()   # the relay's thread has seen the cut begin
        self.thread = threading.Thread(target=self._run, name='pg-relay', daemon=True)
        self.thread.start()

    def url(self, url: str) -> str:
        """``url`` (the server's) through this relay."""
        return url.replace(f':{self.upstream[1]}/', f':{self.port}/')

    def cut(self, seconds: float) -> float:
        """Nothing passes for ``seconds`` from now (from the return of this call: nothing is
        forwarded after it); returns when it ends (time.monotonic())."""
        self._seen_cut.clear()
        self.until = time.monotonic() + seconds
        self.cuts += 1
        self._seen_cut.wait(5)
        return self.until

    def ports(self) -> list[int]:
        """The local ports of the relay's connections to the server (its ``client_port`` there)."""
        found = []
        for a, b in list(self.pairs.items()):
            if b is not None and a.getpeername()[1] == self.upstream[1]:
                found.append(a.getsockname()[1])
        return found

    @property
    def is_cut(self) -> bool:
        return time.monotonic() < self.until

    def close(self) -> None:
        self.closed = True
        self.thread.join(3)
        for a, b in list(self.pairs.items()):
            for s in (a, b):
                if s is not None:
                    s.close()
        self.listener.close()

    def _drop(self, s: socket.socket) -> None:
        peer = self.pairs.pop(s, None)
        self.held.discard(s)
        s.close()
        if peer is not None:
            self.pairs.pop(peer, None)
            self.held.discard(peer)
            peer.close()

    def _run(self) -> None:
        was_cut = False
        while not self.closed:
            cut = self.is_cut
            if was_cut and not cut:           # the link is back: what lived through it is dead
                for s in list(self.held):
                    if s in self.pairs or s in self.held:
                        self._drop(s)
            if cut:
                self.held.update(self.pairs)
                self._seen_cut.set()
            was_cut = cut
            readable = [self.listener] + ([] if cut else list(self.pairs))
            sel = selectors.DefaultSelector()
            for s in readable:
                sel.register(s, selectors.EVENT_READ)
            events = sel.select(timeout=0.05)
            sel.close()
            for key, _ in events:
                s = key.fileobj
                if s is self.listener:
                    try:
                        client, _ = self.listener.accept()
                    except OSError:
                        continue
                    if self.is_cut:
                        self.pairs[client] = None     # held: it never reaches the server
                        self.held.add(client)
                        continue
                    try:
                        server = socket.create_connection(self.upstream, timeout=3)
                    except OSError:
                        client.close()
                        continue
                    self.pairs[client], self.pairs[server] = server, client
                    continue
                if s not in self.pairs:
                    continue
                try:
                    data = s.recv(65536)
                except OSError:
                    data = b''
                peer = self.pairs.get(s)
                if not data or peer is None:
                    self._drop(s)
                    continue
                if self.is_cut:      # read just as the cut began: lost with the link
                    self.held.update((s, peer))
                    continue
                try:
                    peer.sendall(data)
                except OSError:
                    self._drop(s)
