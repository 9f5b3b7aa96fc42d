"""The sim's timers alone: 30 robots' timers at 62.5 Hz doing nothing, CPU per tick.

    .venv/bin/python -m tests.bench.timers
    PYTHONPATH=OTHER_CHECKOUT .venv/bin/python -m tests.bench.timers   # another version, same way

Process CPU time over 5 s, so the figure holds on a busy machine (what the other processes take
is not counted); the class load's share of it (``lesson``) is the rest of the tick.
"""

from __future__ import annotations

import asyncio
import time

from gateway.backends.sim.graph import Graph

TIMERS, PERIOD, SECONDS = 30, 0.016, 5.0


async def measure() -> str:
    graph = Graph()
    nodes = [graph.node(f'/n{i}') for i in range(TIMERS)]
    count = [0]

    def tick() -> None:
        count[0] += 1

    for node in nodes:
        node.create_timer(PERIOD, tick)
    await asyncio.sleep(0.5)
    cpu0, t0, n0 = time.process_time(), time.monotonic(), count[0]
    await asyncio.sleep(SECONDS)
    cpu, wall, n = time.process_time() - cpu0, time.monotonic() - t0, count[0] - n0
    for node in nodes:
        node.destroy()
    return (f'{TIMERS} timers at {1 / PERIOD:.1f} Hz: {n / wall:.0f} ticks/s, CPU {100 * cpu / wall:.1f} % '
            f'of a core, {1e6 * cpu / n:.1f} us per tick')


if __name__ == '__main__':
    print(asyncio.run(measure()))
