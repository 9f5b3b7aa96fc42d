"""The publish door's rules per message, in-process (no socket, no backend publish): a station's pose
topic (no command: the stations' names rule, the program reports', the attempts') and its cmd_vel
(the driver lease, clamps), from the lease holder, with 30 stations and --exclusive-control.

    .venv/bin/python -m tests.bench.door               # about 10 s
    (cd /tmp/old && /path/to/.venv/bin/python -m tests.bench.door)   # the same on another checkout

Prints the median of 7 runs of 20,000 messages each, in microseconds a message."""

from __future__ import annotations

import asyncio
import statistics
import time
from dataclasses import replace

from gateway import rules
from gateway.backends.base import QoS
from gateway.backends.sim import SimBackend
from gateway.bridge.gateway import Gateway
from gateway.settings import SafetySettings, Settings

TWIST = {'linear': {'x': 0.5, 'y': 0.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}
POSE = {'x': 1.0, 'y': 1.0, 'theta': 0.0, 'linear_velocity': 0.0, 'angular_velocity': 0.0}


async def measure(runs: int = 7, n: int = 20000) -> dict:
    backend = SimBackend(demo=False)
    await backend.start()
    gw = Gateway(replace(Settings(), safety=SafetySettings(exclusive_control=True, cmd_timeout=0)), backend)
    composed = rules.compose(gw.rule_doors())
    gw.install(composed)
    gw.hooks.seal(composed.hooks)
    composed.stations._stations = tuple(f'/s{i:02d}' for i in range(1, 31))   # as a --fleet 30 finds them
    composed.stations._stations_at = float('inf')
    ada = gw.open_sender('ada', 'operator', person='user ada')
    pose = gw.publisher('/s07/turtle1/pose', 'turtlesim/msg/Pose', QoS())
    cmd = gw.publisher('/s07/turtle1/cmd_vel', 'geometry_msgs/msg/Twist', QoS())
    for rule in gw.rules:      # her first command takes the lease
        rule(ada, cmd, TWIST, None)
    out = {}
    for name, pub, message in (('pose', pose, POSE), ('cmd_vel', cmd, TWIST)):
        times = []
        for _ in range(runs):
            t0 = time.perf_counter()
            for _ in range(n):
                msg = message
                for rule in gw.rules:
                    msg = rule(ada, pub, msg, None)
            times.append((time.perf_counter() - t0) / n * 1e6)
        out[name] = statistics.median(times)
    await gw.shutdown()
    await backend.stop()
    return out


def main() -> None:
    with open('/proc/loadavg') as f:
        load = f.read().split()[0]
    figures = asyncio.run(measure())
    print(', '.join(f'{k} {v:.2f} us a message' for k, v in figures.items()) + f' (load {load})')


if __name__ == '__main__':
    main()
