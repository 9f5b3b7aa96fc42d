"""A plain rosbridge teleop with roslibpy: ``Topic.publish`` with no stamp, at 10 Hz while a key is
held; on release it just stops sending. Run as a program (in a network namespace of the home-link
tests), one command per stdin line, one answer per stdout line, as tests/node/plain-driver.mjs:
``hold X``, ``release``, ``sync`` (answered ``synced`` once a rosapi call on this connection
returns: everything sent before it arrived), ``quit``; ``ready`` first, once connected.

    python -m tests.support.plain_driver HOST PORT TOPIC
"""

from __future__ import annotations

import sys
import threading

import roslibpy


def main(host: str, port: int, topic: str) -> None:
    ros = roslibpy.Ros(host, port)
    ros.run(timeout=20)
    cmd = roslibpy.Topic(ros, topic, 'geometry_msgs/msg/Twist')
    clock = roslibpy.Service(ros, '/rosapi/get_time', 'rosapi_msgs/srv/GetTime')
    held = threading.Event()
    speed = [0.0]
    done = threading.Event()

    def drive() -> None:
        while not done.is_set():
            if held.is_set():
                cmd.publish(roslibpy.Message({'linear': {'x': speed[0], 'y': 0.0, 'z': 0.0},
                                              'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}))
            done.wait(0.1)

    threading.Thread(target=drive, daemon=True).start()
    print('ready', flush=True)
    for line in sys.stdin:
        word, _, arg = line.strip().partition(' ')
        if word == 'hold':
            speed[0] = float(arg)
            held.set()
        elif word == 'release':
            held.clear()
        elif word == 'sync':
            clock.call(roslibpy.ServiceRequest({}), lambda _r: print('synced', flush=True),
                       lambda e: print(f'failed {e}', flush=True))
        elif word == 'quit':
            break
    done.set()
    ros.close()


if __name__ == '__main__':
    main(sys.argv[1], int(sys.argv[2]), sys.argv[3])
