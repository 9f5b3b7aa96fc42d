"""A fleet of namespaced stations (--fleet 3) with a turtle and a rover each, and claiming one.

This gateway runs at --sim-speed 2: two simulated seconds per real second.
"""

from __future__ import annotations

import json

import pytest
import roslibpy

from tests.support.ros import Inbox, call, client, stream, twist
from tests.support.wait import wait_for

CENTRE = 5.544445


@pytest.fixture(scope='module')
def ros(fleet_gw):
    with client(fleet_gw) as ros:
        yield ros


def claim(ros) -> dict:
    return call(ros, '/fleet/claim', 'std_srvs/srv/Trigger')


def owners(ros) -> list[str]:
    box = []
    topic = roslibpy.Topic(ros, '/rosgate/stations', 'std_msgs/msg/String')
    topic.subscribe(lambda m: box.append(json.loads(m['data'])))
    wait_for(lambda: box, 5)
    topic.unsubscribe()
    return sorted(box[-1]['owners'])


def test_claiming_a_station(ros, fleet_gw):
    """The gateway hands stations out (gateway/rules/stations.py): one per person, here per connection."""
    call(ros, '/fleet/release_all', 'std_srvs/srv/Empty')
    assert claim(ros) == {'success': True, 'message': '/s01'}
    assert claim(ros) == {'success': True, 'message': '/s01'}      # the same client keeps its station
    with client(fleet_gw) as other:
        assert claim(other) == {'success': True, 'message': '/s02'}
        assert owners(ros) == ['/s01', '/s02']
        assert call(other, '/s02/fleet/release', 'std_srvs/srv/Trigger')['success'] is True
        assert call(other, '/s02/fleet/release', 'std_srvs/srv/Trigger')['success'] is False
        # watching is not claiming: a station someone only watches is handed out
        poses = Inbox(other, '/s02/turtle1/pose', 'turtlesim/msg/Pose')
        poses.wait()
        with client(fleet_gw) as third:
            assert claim(third) == {'success': True, 'message': '/s02'}
            assert call(third, '/s02/fleet/release', 'std_srvs/srv/Trigger')['success'] is True
            # one someone drives is not
            roslibpy.Topic(other, '/s02/cmd_vel', 'geometry_msgs/msg/TwistStamped').advertise()
            call(other, '/rosapi/get_time', 'rosapi/srv/GetTime')   # its advertise has been handled
            assert claim(third) == {'success': True, 'message': '/s03'}
            with client(fleet_gw) as fourth:
                refused = claim(fourth)
                assert refused['success'] is False and 'taken' in refused['message']
    call(ros, '/fleet/release_all', 'std_srvs/srv/Empty')
    assert owners(ros) == []


def test_every_station_has_its_own_robots(ros):
    topics = dict(zip(*call(ros, '/rosapi/topics', 'rosapi_msgs/srv/Topics').values()))
    for ns in ('/s01', '/s02', '/s03'):
        assert topics[f'{ns}/turtle1/pose'] == 'turtlesim/msg/Pose'
        assert topics[f'{ns}/cmd_vel'] == 'geometry_msgs/msg/TwistStamped'
        assert topics[f'{ns}/scan'] == 'sensor_msgs/msg/LaserScan'
        assert topics[f'{ns}/world/markers'] == 'visualization_msgs/msg/MarkerArray'
        assert ros.get_service_type(f'{ns}/spawn') == 'turtlesim/srv/Spawn'
        assert ros.get_service_type(f'{ns}/reset_world') == 'std_srvs/srv/Empty'
    assert '/turtle1/pose' not in topics and '/cmd_vel' not in topics and '/s04/cmd_vel' not in topics
    assert {'/s02/turtlesim', '/s02/rover', '/fleet'} <= set(ros.get_nodes())
    assert roslibpy.Param(ros, '/s02/turtlesim:background_g').get(timeout=5) == 86
    assert roslibpy.Param(ros, '/fleet:namespaces').get(timeout=5) == ['/s01', '/s02', '/s03']


def test_stations_move_independently(ros):
    turtle1 = Inbox(ros, '/s01/turtle1/pose', 'turtlesim/msg/Pose')
    turtle2 = Inbox(ros, '/s02/turtle1/pose', 'turtlesim/msg/Pose')
    odom1 = Inbox(ros, '/s01/odom', 'nav_msgs/msg/Odometry')
    odom2 = Inbox(ros, '/s02/odom', 'nav_msgs/msg/Odometry')
    try:
        turtle1.wait()
        odom1.wait()
        roslibpy.Topic(ros, '/s02/turtle1/cmd_vel', 'geometry_msgs/msg/Twist').publish(
            roslibpy.Message(twist(1.0)))
        stamped = roslibpy.Topic(ros, '/s02/cmd_vel', 'geometry_msgs/msg/TwistStamped')
        stream(stamped, {'header': {'stamp': {'sec': 0, 'nanosec': 0}, 'frame_id': 's02/base_link'},
                         'twist': twist(0.5)}, 0.6)
        moved = odom2.wait(lambda m: m['pose']['pose']['position']['x'] > 0.1)
        assert moved['header']['frame_id'] == 's02/odom' and moved['child_frame_id'] == 's02/base_link'
        stopped = turtle2.wait(lambda m: m['x'] > CENTRE and m['linear_velocity'] == 0.0)
        assert stopped['x'] == pytest.approx(CENTRE + 1.0, abs=0.05)   # 1 m/s until 1 simulated second
        started = next(t for t, m in turtle2.items if m['linear_velocity'] > 0)
        halted = next(t for t, m in turtle2.items if m is stopped)
        assert 0.35 < halted - started < 0.7                            # half a real second
        assert turtle1.last['x'] == pytest.approx(CENTRE, abs=1e-4)
        assert odom1.last['pose']['pose']['position']['x'] == 0.0
    finally:
        for inbox in (turtle1, turtle2, odom1, odom2):
            inbox.close()


def test_each_station_draws_its_own_world(ros):
    markers = Inbox(ros, '/s03/world/markers', 'visualization_msgs/msg/MarkerArray')
    try:
        def shown():
            found = {}
            for msg in markers.messages:
                for m in msg['markers']:
                    found.setdefault(m['ns'], {})[m['id']] = m
            return found if {'bounds', 'walls', 'robots'} <= set(found) else None

        view = wait_for(shown)
        assert sorted(m['type'] for m in view['bounds'].values()) == [1, 4]   # turtlesim square, maze outline
        assert len(view['walls']) == 9
        assert {m['text'] for m in view['robots'].values()} == {'turtle1', 'rover'}
    finally:
        markers.close()
