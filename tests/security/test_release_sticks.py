"""The teacher's Release sticks as her Stop does, and one person's clients share her station
(gateway/rules/stations.py, lease.py): --fleet 2 --exclusive-control --auth, raw rosbridge clients."""

from __future__ import annotations

import json

from tests.support.auth import TOKENS
from tests.support.wsclient import TWIST, Client, twist

DRIVER, STATIONS = '/rosgate/driver', '/rosgate/stations'
S01 = '/s01/turtle1/cmd_vel'


def latest(watcher: Client, topic: str, predicate) -> dict:
    return json.loads(watcher.next_message(topic, lambda m: predicate(json.loads(m['data'])), timeout=10)['data'])


def test_the_teachers_release_holds_until_she_claims_again(launch, tokens_file):
    gw = launch('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--auth', tokens_file,
                '--cmd-timeout', '0')
    with Client(gw.ws_url, TOKENS['admin']) as teacher, Client(gw.ws_url, TOKENS['operator']) as ide, \
            Client(gw.ws_url, TOKENS['operator']) as teleop:
        teacher.subscribe(DRIVER, 'std_msgs/msg/String')
        assert ide.call('/fleet/claim')['values'] == {'success': True, 'message': '/s01'}
        assert teleop.refusal({'op': 'publish', 'topic': S01, 'type': TWIST, 'msg': twist(0.5)}) is None
        latest(teacher, DRIVER, lambda d: (d['drivers']['/s01'] or {}).get('name') == 'alice')

        # Release: the claim, the lease and the stop go in one step
        assert teacher.call('/s01/fleet/release')['values']['success'] is True
        state = latest(teacher, DRIVER, lambda d: d['drivers']['/s01'] is None)
        assert '/s01' not in state['halted']
        # none of her clients takes it back by itself, or by Take
        refusal = teleop.refusal({'op': 'publish', 'topic': S01, 'msg': twist(0.5)})
        assert refusal and 'teacher released /s01' in refusal['msg'] and 'Claim a robot' in refusal['msg'], refusal
        assert teleop.refusal({'op': 'publish', 'topic': S01, 'msg': twist()}) is None      # a zero passes
        assert teleop.refusal({'op': 'publish', 'topic': '/rosgate/control', 'type': 'std_msgs/msg/String',
                               'msg': {'data': 'take-if-free /s01'}}) is None
        refusal = ide.refusal({'op': 'publish', 'topic': '/rosgate/control', 'type': 'std_msgs/msg/String',
                               'msg': {'data': 'take /s01'}})
        assert refusal and 'Claim a robot' in refusal['msg'], refusal
        # a stop of the released station on top: still her Claim that resolves it (no internal error)
        teacher.publish('/rosgate/control', {'data': 'stop /s01'}, 'std_msgs/msg/String')
        refusal = ide.refusal({'op': 'publish', 'topic': '/rosgate/control', 'type': 'std_msgs/msg/String',
                               'msg': {'data': 'take /s01'}})
        assert refusal and 'released /s01' in refusal['msg'], refusal
        assert teacher.call('/s01/fleet/release')['values']['success'] is False   # not claimed; the stop ends
        teacher.call('/rosapi/get_time')
        assert latest(teacher, DRIVER, lambda d: True)['drivers']['/s01'] is None
        # another student may have it at once
        with Client(gw.ws_url, TOKENS['operator2']) as bob:
            assert bob.call('/s01/fleet/claim')['values'] == {'success': True, 'message': '/s01'}
            assert bob.refusal({'op': 'publish', 'topic': S01, 'type': TWIST, 'msg': twist(0.2)}) is None
            teacher.call('/fleet/release_all', {})
            latest(teacher, DRIVER, lambda d: d['drivers']['/s01'] is None)
        # her deliberate claim ends the bar
        assert ide.call('/fleet/claim')['values']['success'] is True
        assert teleop.refusal({'op': 'publish', 'topic': S01, 'msg': twist(0.5)}) is None


def test_one_persons_clients_share_her_station_without_a_word(launch, tokens_file):
    gw = launch('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--auth', tokens_file,
                '--cmd-timeout', '0')
    with Client(gw.ws_url, TOKENS['operator']) as ide, Client(gw.ws_url, TOKENS['operator']) as teleop, \
            Client(gw.ws_url, TOKENS['operator2']) as bob, Client(gw.ws_url, TOKENS['viewer']) as watcher:
        watcher.subscribe(DRIVER, 'std_msgs/msg/String')
        assert ide.call('/fleet/claim')['values']['message'] == '/s01'
        for turn in range(3):
            for client, x in ((ide, 0.3), (teleop, 0.4)):
                assert client.refusal({'op': 'publish', 'topic': S01, 'type': TWIST, 'msg': twist(x)}) is None, turn
                held = latest(watcher, DRIVER, lambda d: (d['drivers']['/s01'] or {}).get('name') == 'alice')
                assert held['drivers']['/s01']['owner'] is True
        # another person is refused, and told what resolves it
        refusal = bob.refusal({'op': 'publish', 'topic': S01, 'type': TWIST, 'msg': twist(0.3)})
        assert 'is driving /s01' in refusal['msg'] and 'Claim a robot' in refusal['msg'], refusal


def browser(gw, id: str) -> Client:
    """A page of browser ``id`` (with auth off its id cookie is who the person is)."""
    return Client(gw.ws_url, additional_headers={'Cookie': f'rosgate_browser={id}'})


def take(client: Client, ns: str) -> dict | None:
    return client.refusal({'op': 'publish', 'topic': '/rosgate/control', 'type': 'std_msgs/msg/String',
                           'msg': {'data': f'take {ns}'}})


def test_with_auth_off_a_take_of_a_released_then_stopped_station_is_refused_in_words(launch):
    gw = launch('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--cmd-timeout', '0')
    with browser(gw, 'teacher-browser-0001') as teacher, browser(gw, 'student-browser-0002') as ide, \
            browser(gw, 'student-browser-0003') as bob:
        teacher.subscribe(DRIVER, 'std_msgs/msg/String')
        assert ide.call('/fleet/claim')['values'] == {'success': True, 'message': '/s01'}
        assert ide.refusal({'op': 'publish', 'topic': S01, 'type': TWIST, 'msg': twist(0.5)}) is None
        latest(teacher, DRIVER, lambda d: d['drivers']['/s01'] is not None)
        # the teacher's Release, then her Stop of the station nobody owns now
        assert teacher.call('/s01/fleet/release')['values']['success'] is True
        assert teacher.refusal({'op': 'publish', 'topic': '/rosgate/control', 'type': 'std_msgs/msg/String',
                                'msg': {'data': 'stop /s01'}}) is None
        latest(teacher, DRIVER, lambda d: '/s01' in d['halted'] and d['drivers']['/s01'] is None)
        # the released browser's Take: a refusal that says the station is nobody's and what resolves it
        refusal = take(ide, '/s01')
        assert refusal and 'internal error' not in refusal['msg'], refusal
        assert 'stopped /s01; nobody owns /s01 now' in refusal['msg'], refusal
        assert 'released /s01' in refusal['msg'] and 'Claim a robot' in refusal['msg'], refusal
        # every client carries on: another browser takes the free station (the table's grant) and drives
        assert take(bob, '/s01') is None
        latest(teacher, DRIVER, lambda d: d['drivers']['/s01'] is not None and '/s01' not in d['halted'])
        assert bob.refusal({'op': 'publish', 'topic': S01, 'type': TWIST, 'msg': twist(0.2)}) is None
        # and the released browser claims a station of her own
        assert ide.call('/fleet/claim')['values'] == {'success': True, 'message': '/s02'}
