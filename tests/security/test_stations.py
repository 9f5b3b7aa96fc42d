"""Stations belong to people (gateway/rules/stations.py), the teacher's stop sticks, and a
student's robot-side run drives her own station and gives it back: --fleet 3 --exclusive-control
--auth, over roslibpy with one token per person."""

from __future__ import annotations

import json

import pytest
import roslibpy

from tests.support.auth import TOKENS
from tests.support.ros import client
from tests.support.wait import wait_for

TWIST = 'geometry_msgs/msg/Twist'
TRIGGER = 'std_srvs/srv/Trigger'


@pytest.fixture(scope='module')
def fleet(start_gateway, tokens_file):
    return start_gateway('--robot', 'turtlesim', '--fleet', '3', '--exclusive-control', '--auth', tokens_file,
                         '--cmd-timeout', '0', '--claim-grace', '0.5')


def call(ros, service: str, type_: str = TRIGGER) -> dict:
    return roslibpy.Service(ros, service, type_).call(roslibpy.ServiceRequest({}), timeout=10)


def refused(ros, service: str, type_: str = TRIGGER) -> str:
    with pytest.raises(Exception) as e:
        call(ros, service, type_)
    return str(e.value)


def announced(ros, topic: str) -> dict:
    box = []
    t = roslibpy.Topic(ros, topic, 'std_msgs/msg/String')
    t.subscribe(lambda m: box.append(json.loads(m['data'])))
    wait_for(lambda: box, 10)
    t.unsubscribe()
    return box[-1]


def control(ros, word: str) -> None:
    roslibpy.Topic(ros, '/rosgate/control', 'std_msgs/msg/String').publish(roslibpy.Message({'data': word}))


def drive(ros, ns: str, x: float = 0.3) -> None:
    roslibpy.Topic(ros, f'{ns}/turtle1/cmd_vel', TWIST).publish(roslibpy.Message({'linear': {'x': x}}))


def driver(ros, ns: str):
    return announced(ros, '/rosgate/driver')['drivers'].get(ns)


def test_a_station_is_a_persons_and_comes_back_to_them(fleet):
    with client(fleet, TOKENS['admin']) as teacher:
        call(teacher, '/fleet/release_all', 'std_srvs/srv/Empty')
        with client(fleet, TOKENS['operator']) as alice:
            assert call(alice, '/fleet/claim') == {'success': True, 'message': '/s01'}
            assert call(alice, '/fleet/claim') == {'success': True, 'message': '/s01'}   # a second tab: the same
        # alice has gone for longer than a script's grace; bob arrives and gets the next one
        with client(fleet, TOKENS['operator2']) as bob:
            wait_for(lambda: announced(bob, '/rosgate/stations')['owners'].get('/s01', {}).get('name') == 'alice', 5)
            assert call(bob, '/fleet/claim') == {'success': True, 'message': '/s02'}
            assert 'alice\'s station' in call(bob, '/s01/fleet/claim')['message']
            with client(fleet, TOKENS['operator']) as alice:
                assert call(alice, '/fleet/claim') == {'success': True, 'message': '/s01'}
            # the teacher releases alice's station; a script takes the last free one
            assert call(teacher, '/s01/fleet/release')['success'] is True
            info = announced(teacher, '/rosgate/stations')
            assert '/s01' not in info['owners'] and info['released']['/s01']['by'] == 'teacher'
            assert info['owners']['/s02']['name'] == 'bob'
        call(teacher, '/fleet/release_all', 'std_srvs/srv/Empty')
        assert announced(teacher, '/rosgate/stations')['owners'] == {}


def test_another_person_cannot_release_or_drive_a_station(fleet):
    with client(fleet, TOKENS['admin']) as teacher, client(fleet, TOKENS['operator']) as alice, \
            client(fleet, TOKENS['operator2']) as bob:
        call(teacher, '/fleet/release_all', 'std_srvs/srv/Empty')
        assert call(alice, '/fleet/claim')['message'] == '/s01'
        assert 'only they or an admin' in refused(bob, '/s01/fleet/release')
        drive(bob, '/s01')            # refused: alice's station, though nobody drives it
        call(bob, '/rosapi/get_time', 'rosapi/srv/GetTime')
        assert driver(teacher, '/s01') is None
        drive(alice, '/s01')
        wait_for(lambda: (driver(teacher, '/s01') or {}).get('name') == 'alice', 5)
        assert driver(teacher, '/s01')['owner'] is True
        call(teacher, '/fleet/release_all', 'std_srvs/srv/Empty')


def test_a_stop_sticks_until_the_owner_takes(fleet):
    with client(fleet, TOKENS['admin']) as teacher, client(fleet, TOKENS['operator']) as alice, \
            client(fleet, TOKENS['operator2']) as bob:
        call(teacher, '/fleet/release_all', 'std_srvs/srv/Empty')
        assert call(alice, '/fleet/claim')['message'] == '/s01'
        drive(alice, '/s01')
        wait_for(lambda: (driver(teacher, '/s01') or {}).get('name') == 'alice', 5)
        control(teacher, 'stop /s01')
        wait_for(lambda: '/s01' in announced(teacher, '/rosgate/driver')['halted'], 5)
        # nobody takes it by itself: not alice's commands, not bob's take-if-free, not bob's Take
        drive(alice, '/s01')
        control(alice, 'take-if-free /s01')
        control(bob, 'take /s01')
        with client(fleet, TOKENS['operator']) as alice2:   # alice's page reloaded
            control(alice2, 'take-if-free /s01')
            drive(alice2, '/s01')
            call(alice2, '/rosapi/get_time', 'rosapi/srv/GetTime')
        call(bob, '/rosapi/get_time', 'rosapi/srv/GetTime')
        info = announced(teacher, '/rosgate/driver')
        assert info['drivers']['/s01'] is None and '/s01' in info['halted']
        # her deliberate Take resumes
        control(alice, 'take /s01')
        wait_for(lambda: (driver(teacher, '/s01') or {}).get('name') == 'alice', 5)
        assert '/s01' not in announced(teacher, '/rosgate/driver')['halted']
        # the teacher's Release also ends a stop
        control(teacher, 'stop /s01')
        wait_for(lambda: '/s01' in announced(teacher, '/rosgate/driver')['halted'], 5)
        control(teacher, 'release /s01')
        wait_for(lambda: '/s01' not in announced(teacher, '/rosgate/driver')['halted'], 5)
        call(teacher, '/fleet/release_all', 'std_srvs/srv/Empty')


def test_a_station_lapses_after_its_owner_is_away_for_claim_idle(start_gateway, tokens_file):
    gw = start_gateway('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--auth', tokens_file,
                       '--claim-idle', '1')
    with client(gw, TOKENS['admin']) as teacher:
        with client(gw, TOKENS['operator']) as alice:
            assert call(alice, '/fleet/claim')['message'] == '/s01'
            held = announced(teacher, '/rosgate/stations')['owners']
            assert held['/s01']['name'] == 'alice'
        wait_for(lambda: '/s01' not in announced(teacher, '/rosgate/stations')['owners'], 10)
        assert announced(teacher, '/rosgate/stations')['released'] == {}   # it lapsed: nobody released it
