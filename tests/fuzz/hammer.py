"""Measure a gateway under hostile load (not part of `make test`):

    .venv/bin/python -m tests.fuzz.hammer --ops 100000

1. ``--ops`` fuzzed frames (tests/fuzz/frames.py) over ``--connections`` connections at once,
   each sending batches followed by a barrier call: counts connections the server dropped
   (1006: no close frame), other closes, ops with a definite defect left without an error status,
   and "internal error" statuses; the gateway's RSS before and after.
2. A client that stops reading and keeps calling ``/rosapi/topics_and_raw_types``: the server's
   RSS growth while it floods, how it ended, and RSS after it left.
3. A websocket upgrade as a page on a rebound domain would send it (Host and Origin evil.example).
"""

from __future__ import annotations

import argparse
import json
import random
import socket
import threading
import time
import urllib.request
from collections.abc import Callable

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from tests.support.fuzzclient import Closed, FuzzConn
from tests.support.fuzzframes import frame
from tests.support.process import GatewayProcess, proc_bytes
from tests.support.rawsocket import upgrade_request
from tests.support.wait import wait_for

SET_LEVEL = json.dumps({'op': 'set_level', 'level': 'error'})
MB = 2**20


class Tally:
    def __init__(self):
        self.lock = threading.Lock()
        self.frames = self.bad = self.unanswered = self.internal = 0
        self.closes: dict[int, int] = {}
        self.examples: list = []

    def add(self, **counts):
        with self.lock:
            for k, v in counts.items():
                setattr(self, k, getattr(self, k) + v)


def fuzz_worker(url: str, ops: int, seed: int, tally: Tally) -> None:
    rng = random.Random(seed)
    conn = FuzzConn(url)
    sent = 0
    while sent < ops:
        frames = [frame(rng) for _ in range(rng.randrange(1, 11))]
        try:
            for f in frames:
                if f.bad_id or f.close:
                    conn.send(SET_LEVEL)
                conn.send(f.payload, f.text)   # a few text frames are not UTF-8: those close 1007
            got = conn.barrier(120)
        except Closed as closed:
            with tally.lock:
                tally.closes[closed.code] = tally.closes.get(closed.code, 0) + 1
                if closed.code == 1006 and len(tally.examples) < 5:
                    tally.examples.append(('dropped', [f.payload for f in frames]))
            conn = FuzzConn(url)
            sent += len(frames)
            continue
        answered = {m.get('id') for m in got if m.get('op') == 'status' and m.get('level') == 'error'}
        missing = [f.payload for f in frames if f.bad_id and f.bad_id not in answered]
        internal = sum(1 for m in got if m.get('op') == 'status' and 'internal error' in m.get('msg', ''))
        if (missing or internal) and len(tally.examples) < 5:
            with tally.lock:
                tally.examples.append(('unanswered' if missing else 'internal', [f.payload for f in frames]))
        tally.add(frames=len(frames), bad=sum(1 for f in frames if f.bad_id), unanswered=len(missing),
                  internal=internal)
        sent += len(frames)
    conn.close()


def fuzz(url: str, pid: int, ops: int, connections: int, seed: int) -> None:
    warm = FuzzConn(url)
    warm.barrier()
    warm.close()
    rss0 = proc_bytes(pid)
    tally = Tally()
    t0 = time.monotonic()
    threads = [threading.Thread(target=fuzz_worker, args=(url, ops // connections, seed + i, tally))
               for i in range(connections)]
    for t in threads:
        t.start()
    peak = rss0
    while any(t.is_alive() for t in threads):
        peak = max(peak, proc_bytes(pid))
        time.sleep(0.2)
    rss1 = proc_bytes(pid)
    print(f'fuzz: {tally.frames} frames ({tally.bad} with a definite defect) over {connections} connections '
          f'in {time.monotonic() - t0:.1f} s')
    print(f'fuzz: closes by code {tally.closes or "{} (none)"}; server-initiated 1006: {tally.closes.get(1006, 0)}')
    print(f'fuzz: defective ops without an error status: {tally.unanswered}; internal errors: {tally.internal}')
    print(f'fuzz: RSS {rss0 / MB:.1f} MiB before, {peak / MB:.1f} MiB peak, {rss1 / MB:.1f} MiB after '
          f'(growth {(rss1 - rss0) / MB:+.1f} MiB)')
    for kind, frames in tally.examples:
        print(f'  example ({kind}): {frames!r}'[:2000])


def clients(port: int) -> int:
    with urllib.request.urlopen(f'http://127.0.0.1:{port}/health', timeout=10) as r:
        return json.load(r)['clients']


def non_reader(url: str, port: int, pid: int, seconds: float, rate: float, log: Callable[[], str]) -> None:
    rss0 = proc_bytes(pid)
    ws = connect(url, max_size=None, compression=None, open_timeout=10, max_queue=1, legacy=True)
    peak, calls, t0, ended = rss0, 0, time.monotonic(), 'still open'
    try:
        while time.monotonic() - t0 < seconds:
            ws.send(json.dumps({'op': 'call_service', 'service': '/rosapi/topics_and_raw_types', 'id': f'c{calls}'}))
            calls += 1
            if calls % 100 == 0:
                peak = max(peak, proc_bytes(pid))
            if rate:
                time.sleep(max(0.0, t0 + calls / rate - time.monotonic()))
    except ConnectionClosed:
        pass
    during = proc_bytes(pid)
    peak = max(peak, during)
    try:   # read what is left to learn how the server ended it
        while True:
            ws.recv(timeout=30)
    except ConnectionClosed as e:
        ended = f'closed {e.rcvd.code} {e.rcvd.reason!r}' if e.rcvd else 'dropped (1006)'
    except TimeoutError:
        ended = 'no close within 30 s'
    ws.close()
    wait_for(lambda: not clients(port), timeout=30)   # the gateway has released the client (and its memory)
    after = proc_bytes(pid)
    said = [line.split(': ', 1)[-1].strip() for line in log().splitlines() if 'does not read its replies' in line]
    print(f'non-reader: {calls} calls in {time.monotonic() - t0:.1f} s; the client saw: {ended}; '
          f'the gateway logged: {said[-1] if said else "nothing"}')
    print(f'non-reader: RSS {rss0 / MB:.1f} MiB before, {peak / MB:.1f} MiB peak (growth {(peak - rss0) / MB:+.1f} MiB), '
          f'{after / MB:.1f} MiB after it left')


def rebinding(port: int) -> None:
    host = f'evil.example:{port}'
    with socket.create_connection(('127.0.0.1', port), timeout=10) as s:
        s.sendall(upgrade_request(host, origin=f'http://{host}'))
        status = s.recv(4096).split(b'\r\n', 1)[0].decode()
        print(f'rebinding upgrade (Host and Origin {host}): {status}')


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--ops', type=int, default=100_000)
    p.add_argument('--connections', type=int, default=4)
    p.add_argument('--seed', type=int, default=1)
    p.add_argument('--flood-seconds', type=float, default=20.0)
    p.add_argument('--flood-rate', type=float, default=500.0, help='calls per second, 0: as fast as possible')
    args = p.parse_args()
    gw = GatewayProcess('--fibonacci-interval', '0.01', '--max-message-size', '262144')
    try:
        fuzz(gw.ws_url, gw.pid, args.ops, args.connections, args.seed)
        non_reader(gw.ws_url, gw.port, gw.pid, args.flood_seconds, args.flood_rate, gw.log_text)
        rebinding(gw.port)
        print(f'gateway alive: {gw.alive}')
    finally:
        gw.stop()


if __name__ == '__main__':
    main()
