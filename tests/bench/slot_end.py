"""How soon a booked slot's end stops the robot, with no page acting (--booking, rules/bookings.py).

    python -m tests.bench.slot_end [--repeat 5]

On a lab gateway (--fleet 2 --auth --exclusive-control --booking --slot-minutes 0.25
--station-reset reset), ``--repeat`` times: alice books a 3 s slot of /s01 and streams
cmd_vel at 20 Hz through it and past its end; a watcher records /s01/turtle1/pose (62.5 Hz in
the sim) with the wall-clock time of arrival. Printed per slot: from the booking's end to the
last pose that moved (the turtle still going), and to the first pose back at the start pose
(the --station-reset). Arrival times include the pose's trip through the gateway to the
watcher, so each figure is late by that much (and by up to one pose period, 16 ms).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import threading
import time
import urllib.request

import roslibpy

from tests.support.auth import TOKENS, tokens_toml
from tests.support.process import GatewayProcess

START = 5.544445


def book(gw, start: float, end: float) -> dict:
    req = urllib.request.Request(gw.http_url + 'api/bookings', method='POST', data=json.dumps(
        {'station': '/s01', 'start': start, 'end': end}).encode())
    req.add_header('Content-Type', 'application/json')
    req.add_header('Authorization', f'Bearer {TOKENS["operator"]}')
    with urllib.request.urlopen(req, timeout=10) as res:
        return json.loads(res.read())


def once(gw, watcher, alice) -> tuple[float, float]:
    poses: list[tuple[float, dict]] = []
    topic = roslibpy.Topic(watcher, '/s01/turtle1/pose', 'turtlesim/msg/Pose')
    topic.subscribe(lambda m: poses.append((time.time(), m)))
    slot = book(gw, time.time() + 1.0, time.time() + 4.0)
    cmd = roslibpy.Topic(alice, '/s01/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
    stop = threading.Event()

    def stream():
        while not stop.is_set():
            cmd.publish(roslibpy.Message({'linear': {'x': 1.0}, 'angular': {'z': 0.5}}))
            time.sleep(0.05)
    thread = threading.Thread(target=stream)
    thread.start()
    try:
        while time.time() < slot['end'] + 2.0:
            time.sleep(0.05)
    finally:
        stop.set()
        thread.join()
        topic.unsubscribe()
    after = [(t, p) for t, p in poses if t > slot['end']]
    home = [t for t, p in after if abs(p['x'] - START) < 1e-3 and abs(p['y'] - START) < 1e-3]
    moving = [t for t, p in after if p['linear_velocity'] != 0 or abs(p['x'] - START) > 1e-3]
    if not home:
        raise RuntimeError('the turtle never came back to its start pose')
    return (max(moving) if moving else slot['end']) - slot['end'], home[0] - slot['end']


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeat', type=int, default=5)
    args = parser.parse_args()
    tokens = os.path.join(tempfile.mkdtemp(prefix='rosgate-bench-'), 'tokens.toml')
    with open(tokens, 'w') as f:
        f.write(tokens_toml())
    gw = GatewayProcess('--robot', 'turtlesim', '--fleet', '2', '--auth', tokens, '--exclusive-control',
                        '--booking', '--slot-minutes', '0.25', '--station-reset', 'reset', '--booking-per-day', '0')
    watcher = roslibpy.Ros(f'ws://{gw.host}:{gw.port}/?token={TOKENS["viewer"]}')
    alice = roslibpy.Ros(f'ws://{gw.host}:{gw.port}/?token={TOKENS["operator"]}')
    try:
        watcher.run(timeout=10)
        alice.run(timeout=10)
        moved, home = zip(*(once(gw, watcher, alice) for _ in range(args.repeat)))
        ms = lambda xs: ' '.join(f'{1000 * x:.0f}' for x in xs)   # noqa: E731
        print(f'slot end -> last moving pose:      median {1000 * statistics.median(moved):.0f} ms, '
              f'max {1000 * max(moved):.0f} ms ({ms(moved)})')
        print(f'slot end -> back at the start pose: median {1000 * statistics.median(home):.0f} ms, '
              f'max {1000 * max(home):.0f} ms ({ms(home)})')
    finally:
        watcher.close()
        alice.close()
        gw.stop()


if __name__ == '__main__':
    main()
