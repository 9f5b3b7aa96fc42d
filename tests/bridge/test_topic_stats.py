"""/rosgate/topic_stats: rates and bandwidths the gateway measures for the topics a page shows, only
while it asks (roslibpy against the sim's rover)."""

from __future__ import annotations

import pytest
import roslibpy

from protocol.convert import from_json, to_cdr
from protocol.msgdefs import Definitions
from tests.support.ros import RosClient
from tests.support.wait import wait_for

STATS = '/rosgate/topic_stats'
TYPE = 'rosgate_msgs/srv/TopicStatistics'
CAMERA = '/camera/image_raw/compressed'


@pytest.fixture(scope='module')
def rover(start_gateway):
    return start_gateway('--robot', 'rover')


@pytest.fixture
def ros(rover):
    c = RosClient(rover)
    yield c
    c.close()


def stats(ros: RosClient, *topics: str) -> dict:
    values = ros.call(STATS, TYPE, {'topics': list(topics)})
    return {t: (values['rates'][i], values['bandwidths'][i], values['windows'][i]) for i, t in enumerate(topics)}


def gateway_subscribes(ros: RosClient, topic: str) -> bool:
    """Whether the gateway's node (/rosgate, or the name the tests give it) subscribes to topic."""
    found = ros.call('/rosapi/subscribers', 'rosapi_msgs/srv/Subscribers', {'topic': topic})['subscribers']
    return any(n.startswith('/rosgate') for n in found)


def test_rates_and_bandwidths_of_the_topics_asked_about(ros, rover):
    odom = ros.watch('/odom', 'nav_msgs/msg/Odometry')
    got = wait_for(lambda: (lambda s: s if s['/odom'][2] >= 2 and s['/odom'][0] > 0 else None)(
        stats(ros, '/odom', '/no/such/topic')), timeout=30, interval=0.3, what='two seconds of /odom measured')
    rate, bandwidth, window = got['/odom']
    assert got['/no/such/topic'] == (-1, -1, -1)
    # every Odometry of the rover has the same size: the bandwidth is the rate times its CDR's length
    msg = wait_for(odom.latest, what='an odometry message')
    defs = Definitions.jazzy()
    size = len(to_cdr(defs, 'nav_msgs/msg/Odometry', from_json(defs, defs.msg('nav_msgs/msg/Odometry'), msg)))
    assert bandwidth == pytest.approx(rate * size, rel=1e-6), (rate, bandwidth, size)
    assert window <= 5.0 + 1e-6


def test_a_topic_is_measured_only_while_asked(ros, rover):
    assert not gateway_subscribes(ros, CAMERA)   # nobody watches the camera: the rover renders nothing
    wait_for(lambda: stats(ros, CAMERA)[CAMERA][0] > 0, timeout=30, interval=0.3, what='the camera measured')
    assert gateway_subscribes(ros, CAMERA)
    rate, bandwidth, _ = stats(ros, CAMERA)[CAMERA]
    assert bandwidth > rate * 1000                      # kilobytes a frame
    # nobody asks any more: the gateway lets the camera go
    wait_for(lambda: not gateway_subscribes(ros, CAMERA), timeout=30, interval=0.3,
             what="the gateway's camera subscription gone")


def test_a_subscribers_topic_stays_when_measuring_ends(ros, rover):
    imu = ros.watch('/imu', 'sensor_msgs/msg/Imu')
    wait_for(lambda: all(s[0] > 0 for s in stats(ros, '/imu', CAMERA).values()), timeout=30, interval=0.3,
             what='/imu and the camera measured')
    # both meters end in one pass: once the camera's subscription is gone, /imu's meter is too
    wait_for(lambda: not gateway_subscribes(ros, CAMERA), timeout=30, interval=0.3,
             what="the camera's meter gone")
    n = len(imu.messages)
    wait_for(lambda: len(imu.messages) >= n + 50, timeout=30, what='fifty more imu messages')
    assert gateway_subscribes(ros, '/imu')


def test_too_many_topics_is_refused(ros):
    with pytest.raises(roslibpy.core.ServiceException) as failed:
        ros.call(STATS, TYPE, {'topics': [f'/t{i}' for i in range(101)]})
    assert 'at most 100 topics' in str(failed.value)
