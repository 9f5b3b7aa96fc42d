"""Fan-out: one publisher here, N subscribers spread over worker processes."""

from __future__ import annotations

import asyncio
import multiprocessing
import time
from collections import Counter

from .ceiling import tune_malloc
from .client import StringFrames, advertise, close_quietly, open_ws, percentile, read_stamp, subscribe
from .flow import publish_at, read_frames, unique_topic
from .servers import ProcMeter, Target, Window

STRING = "std_msgs/msg/String"


def worker_main(url: str, topic: str, count: int, conn, malloc_tune: bool) -> None:
    if malloc_tune:
        tune_malloc()
    asyncio.run(_worker(url, topic, count, conn))


async def _worker(url: str, topic: str, count: int, conn) -> None:
    loop = asyncio.get_running_loop()
    per_seq: Counter[int] = Counter()
    latencies: list[tuple[int, int]] = []
    got = [False] * count
    commands: asyncio.Queue = asyncio.Queue()
    loop.add_reader(conn.fileno(), lambda: commands.put_nowait(conn.recv()))

    def on_frame(index: int, frame: bytes, now: int) -> None:
        got[index] = True
        stamp = read_stamp(frame)
        if stamp is not None:
            per_seq[stamp[0]] += 1
            latencies.append((stamp[0], now - stamp[1]))

    conns = []
    readers = []
    try:
        for index in range(count):
            ws = await open_ws(url)
            conns.append(ws)
            await subscribe(ws, topic, STRING)
            readers.append(asyncio.create_task(
                read_frames(ws, lambda f, n, i=index: on_frame(i, f, n))))
        conn.send(("ready",))
        warm_sent = False
        while True:
            try:
                command = await asyncio.wait_for(commands.get(), 0.02)
            except asyncio.TimeoutError:
                command = None
            if not warm_sent and all(got):
                conn.send(("warm",))
                warm_sent = True
            if command is None:
                continue
            if command[0] == "count":
                _, first, last = command
                conn.send(("count", sum(per_seq[s] for s in range(first, last + 1))))
            elif command[0] == "dump":
                _, first, last = command
                picked = [lat for seq, lat in latencies if first <= seq <= last]
                latencies.clear()
                per_seq.clear()
                conn.send(("dump", picked, time.process_time()))
            elif command[0] == "stop":
                break
    finally:
        for reader in readers:
            reader.cancel()
        await close_quietly(*conns)
        loop.remove_reader(conn.fileno())
        conn.close()


class Workers:
    """Subscriber processes and their pipes, read from the event loop."""

    def __init__(self, url: str, topic: str, total: int, procs: int, malloc_tune: bool) -> None:
        ctx = multiprocessing.get_context("spawn")
        procs = max(1, min(procs, total))
        sizes = [total // procs + (1 if i < total % procs else 0) for i in range(procs)]
        self.pipes = []
        self.procs = []
        self.inbox: list[asyncio.Queue] = []
        loop = asyncio.get_running_loop()
        for size in sizes:
            parent, child = ctx.Pipe()
            proc = ctx.Process(target=worker_main, args=(url, topic, size, child, malloc_tune), daemon=True)
            proc.start()
            child.close()
            queue: asyncio.Queue = asyncio.Queue()
            loop.add_reader(parent.fileno(), self._reader(parent, queue))
            self.pipes.append(parent)
            self.procs.append(proc)
            self.inbox.append(queue)

    @staticmethod
    def _reader(pipe, queue):
        def read() -> None:
            try:
                queue.put_nowait(pipe.recv())
            except EOFError:
                asyncio.get_running_loop().remove_reader(pipe.fileno())
                queue.put_nowait(("eof",))
        return read

    async def expect(self, kind: str, timeout: float) -> list[tuple]:
        replies = []
        for queue in self.inbox:
            reply = await asyncio.wait_for(queue.get(), timeout)
            if reply[0] != kind:
                raise RuntimeError(f"subscriber worker sent {reply[0]!r}, expected {kind!r}")
            replies.append(reply)
        return replies

    async def ask(self, command: tuple, kind: str, timeout: float = 10.0) -> list[tuple]:
        for pipe in self.pipes:
            pipe.send(command)
        return await self.expect(kind, timeout)

    async def stop(self) -> None:
        loop = asyncio.get_running_loop()
        for pipe in self.pipes:
            try:
                pipe.send(("stop",))
            except OSError:
                pass
        for proc in self.procs:
            await loop.run_in_executor(None, proc.join, 10)
            if proc.is_alive():
                proc.kill()
        for pipe in self.pipes:
            try:
                loop.remove_reader(pipe.fileno())
            except (OSError, ValueError):
                pass
            pipe.close()


async def fanout(target: Target, subscribers: int, rate: float, size: int, duration: float,
                 repeats: int, procs: int, malloc_tune: bool = True) -> list[dict]:
    """One run per repeat, all over the same connections."""
    topic = unique_topic("fan")
    frames = StringFrames(topic, size)
    pub = await open_ws(target.url)
    workers = None
    runs = []
    try:
        await advertise(pub, topic, STRING)
        workers = Workers(target.url, topic, subscribers, procs, malloc_tune)
        await workers.expect("ready", 60)
        seq = 0
        deadline = time.monotonic() + 20
        warm = 0
        while warm < len(workers.pipes):  # publish until every subscriber has a message
            if time.monotonic() > deadline:
                raise TimeoutError("subscribers got no message during warm-up")
            await pub.send(frames.frame(seq), text=True)
            seq += 1
            await asyncio.sleep(0.05)
            for queue in workers.inbox:
                while not queue.empty():
                    if queue.get_nowait()[0] != "warm":
                        raise RuntimeError("subscriber worker failed during warm-up")
                    warm += 1
        await asyncio.sleep(0.1)
        for _ in range(repeats):
            cpu0 = sum(r[2] for r in await workers.ask(("dump", 0, -1), "dump"))
            window = Window(ProcMeter(target.pid))
            first = seq
            seq = await publish_at(pub, frames.frame, rate, time.monotonic() + duration, seq)
            last = seq - 1
            expected = subscribers * (last - first + 1)
            delivered = [0]

            async def poll() -> bool:
                counts = await workers.ask(("count", first, last), "count")
                delivered[0] = sum(c[1] for c in counts)
                return delivered[0] >= expected

            settle_deadline = time.monotonic() + 2.0
            while not await poll() and time.monotonic() < settle_deadline:
                await asyncio.sleep(0.02)
            dumps = await workers.ask(("dump", first, last), "dump")
            cpu1 = sum(r[2] for r in dumps)
            figures = window.stop(extra_client_cpu=cpu1 - cpu0)
            lat = sorted(x for r in dumps for x in r[1])
            count = len(lat)
            runs.append({
                "delivered_pct": 100 * count / expected if expected else None,
                "server_cpu_pct": figures["server_cpu_pct"],
                "server_cpu_s_per_1000": None if figures["server_cpu_s"] is None or not count
                else figures["server_cpu_s"] / count * 1000,
                "lat_p50_ms": None if not lat else percentile(lat, 50) / 1e6,
                "lat_p95_ms": None if not lat else percentile(lat, 95) / 1e6,
                "published_hz": (last - first + 1) / duration,
                "client_cpu_pct": figures["client_cpu_pct"],
                "other_cpu_pct": figures["other_cpu_pct"],
            })
    finally:
        if workers is not None:
            await workers.stop()
        await close_quietly(pub)
    return runs

