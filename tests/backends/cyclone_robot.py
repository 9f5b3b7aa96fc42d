"""A "robot" on Eclipse Cyclone DDS, with no ROS at all: the cyclonedds Python binding publishing
and subscribing ROS 2 topics by hand (``rt/`` names, ``pkg::msg::dds_::Type_`` type names).

    python -m tests.backends.cyclone_robot SECONDS

Publishes std_msgs/String "hello N" on /cyclone/chatter at 10 Hz and prints "got DATA" for each
message on /cyclone/echo. Discovery stays on loopback (unicast to 127.0.0.1, the way a ROS 2
node with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST finds its peers).
"""

import os
import sys
import time
from dataclasses import dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

CONFIG = ('<CycloneDDS><Domain Id="any"><General><Interfaces><NetworkInterface name="lo"/></Interfaces>'
          '<AllowMulticast>false</AllowMulticast></General><Discovery><Peers><Peer address="127.0.0.1"/>'
          '</Peers><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>64</MaxAutoParticipantIndex>'
          '</Discovery></Domain></CycloneDDS>')


@dataclass
class String_(IdlStruct, typename='std_msgs::msg::dds_::String_'):   # std_msgs/msg/String on the wire
    data: str


def main(seconds: float) -> None:
    os.environ.setdefault('CYCLONEDDS_URI', CONFIG)   # read when the participant joins the domain
    participant = DomainParticipant(int(os.environ.get('ROS_DOMAIN_ID', '0')))
    qos = Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(10))
    writer = DataWriter(participant, Topic(participant, 'rt/cyclone/chatter', String_), qos=qos)
    reader = DataReader(participant, Topic(participant, 'rt/cyclone/echo', String_), qos=qos)
    print('ready', flush=True)
    end, n = time.monotonic() + seconds, 0
    while time.monotonic() < end:
        writer.write(String_(data=f'hello {n}'))
        n += 1
        for sample in reader.take(N=10):
            print('got', sample.data, flush=True)
        time.sleep(0.1)


if __name__ == '__main__':
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 60.0)
