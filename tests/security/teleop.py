"""A teleop client in its own process: streams a Twist until it is killed.

    python -m tests.security.teleop WS_URL TOPIC [RATE_HZ]
Prints "streaming" once the first command is sent.
"""

import json
import sys
import time

from websockets.sync.client import connect


def main() -> None:
    url, topic = sys.argv[1], sys.argv[2]
    period = 1.0 / float(sys.argv[3]) if len(sys.argv) > 3 else 0.02
    with connect(url, compression=None) as ws:
        ws.send(json.dumps({'op': 'advertise', 'topic': topic, 'type': 'geometry_msgs/msg/Twist'}))
        first = True
        while True:
            ws.send(json.dumps({'op': 'publish', 'topic': topic,
                                'msg': {'linear': {'x': 0.5}, 'angular': {'z': 0.25}}}))
            if first:
                print('streaming', flush=True)
                first = False
            time.sleep(period)


if __name__ == '__main__':
    main()
