"""One driver per robot: --exclusive-control leases each fleet station, robot namespace or
--control-glob group on its own; an admin stops, frees and takes over one station."""

from __future__ import annotations

import json

from tests.support.auth import TOKENS
from tests.support.wsclient import TWIST, Client, is_zero_twist, twist

DRIVER = '/rosgate/driver'


def driver_state(watcher: Client, predicate=lambda d: True) -> dict:
    return json.loads(watcher.next_message(DRIVER, lambda m: predicate(json.loads(m['data'])))['data'])


def holder(state: dict, group: str) -> str | None:
    d = state['drivers'].get(group)
    return d and d['name']


def test_each_fleet_station_has_its_own_driver(launch, tokens_file):
    gw = launch('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--auth', tokens_file,
                '--cmd-timeout', '0')
    s01, s02 = '/s01/turtle1/cmd_vel', '/s02/turtle1/cmd_vel'
    with Client(gw.ws_url, TOKENS['viewer']) as watcher, Client(gw.ws_url, TOKENS['operator']) as alice, \
            Client(gw.ws_url, TOKENS['operator2']) as bob:
        watcher.subscribe(DRIVER, 'std_msgs/msg/String')
        first = driver_state(watcher)
        assert first['stations'] == ['/s01', '/s02'] and first['drivers'] == {'/s01': None, '/s02': None}
        watcher.subscribe(s01, TWIST)
        alice.send({'op': 'set_level', 'level': 'warning'})

        alice.publish(s01, twist(0.5), TWIST)
        assert holder(driver_state(watcher, lambda d: d['drivers']['/s01']), '/s01') == 'alice'
        assert watcher.next_message(s01) == twist(0.5)
        # bob drives the other station at the same time; the first one stays alice's
        assert bob.refusal({'op': 'publish', 'topic': s02, 'type': TWIST, 'msg': twist(0.3)}) is None
        state = driver_state(watcher, lambda d: d['drivers']['/s02'])
        assert holder(state, '/s01') == 'alice' and holder(state, '/s02') == 'bob' and state['driver'] is None
        refusal = bob.refusal({'op': 'publish', 'topic': s01, 'type': TWIST, 'msg': twist(-0.5)})
        assert 'alice (client' in refusal['msg'] and 'is driving /s01' in refusal['msg']
        # a station's services are not commands, but they are its holder's (a teleport moves the robot too)
        refused = bob.call('/s01/turtle1/teleport_relative', {'linear': 0.0, 'angular': 0.0})
        assert refused['result'] is False and 'alice (client' in refused['values'], refused
        assert alice.call('/s01/turtle1/teleport_relative', {'linear': 0.0, 'angular': 0.0})['result']
        bob.publish('/rosgate/control', {'data': 'take /s01'}, id='take1')
        assert 'only an admin can take over' in bob.status('take1')['msg']

        with Client(gw.ws_url, TOKENS['admin']) as teacher:
            # the teacher stops /s01: zero velocity, the lease freed, alice told, pages told (stopped)
            teacher.publish('/rosgate/control', {'data': 'stop /s01'})
            assert watcher.next_message(s01, is_zero_twist) == twist()
            state = driver_state(watcher, lambda d: '/s01' in d['stopped'])
            assert state['drivers']['/s01'] is None and holder(state, '/s02') == 'bob'
            warning = alice.expect(lambda m: m.get('op') == 'status' and m.get('level') == 'warning')
            assert 'teacher (client' in warning['msg'] and 'stopped the robot' in warning['msg']
            # the teacher frees bob's station; an operator may not stop one
            alice.publish('/rosgate/control', {'data': 'stop /s02'}, id='stop1')
            assert 'only an admin' in alice.status('stop1')['msg']
            teacher.publish('/rosgate/control', {'data': 'release /s02'})
            assert driver_state(watcher, lambda d: d['drivers']['/s02'] is None)['drivers']['/s02'] is None

        # take and release one station by name
        bob.publish('/rosgate/control', {'data': 'take /s01'})
        assert holder(driver_state(watcher, lambda d: d['drivers']['/s01']), '/s01') == 'bob'
        bob.publish('/rosgate/control', {'data': 'release'})
        assert driver_state(watcher, lambda d: d['drivers']['/s01'] is None)


def test_control_glob_groups_lease_separately(launch):
    gw = launch('--robot', 'turtlesim', '--exclusive-control', '--control-glob', "['/turtle1/*', '/turtle2/*']",
                '--cmd-timeout', '0')
    with Client(gw.ws_url) as watcher, Client(gw.ws_url + '?name=Ann') as ann, \
            Client(gw.ws_url + '?name=Ben') as ben:
        watcher.subscribe(DRIVER, 'std_msgs/msg/String')
        assert ann.call('/spawn', {'x': 2.0, 'y': 2.0, 'theta': 0.0, 'name': 'turtle2'})['result']
        assert ann.refusal({'op': 'publish', 'topic': '/turtle1/cmd_vel', 'type': TWIST, 'msg': twist(0.2)}) is None
        assert ben.refusal({'op': 'publish', 'topic': '/turtle2/cmd_vel', 'type': TWIST, 'msg': twist(0.2)}) is None
        state = driver_state(watcher, lambda d: d['drivers'].get('/turtle1') and d['drivers'].get('/turtle2'))
        assert holder(state, '/turtle1') == 'Ann' and holder(state, '/turtle2') == 'Ben'
        # a service under a glob is a command of that group
        refusal = ben.refusal({'op': 'call_service', 'service': '/turtle1/teleport_relative',
                               'args': {'linear': 0.0, 'angular': 0.0}})
        assert 'Ann (client' in refusal['msg'] and 'is driving /turtle1' in refusal['msg']


class Graph:
    """A backend's graph introspection, as a real multi-robot graph would answer it."""

    def __init__(self, topics: dict[str, tuple[str, list[str]]]):
        self._topics = topics

    def topics(self):
        return [(name, type) for name, (type, _) in self._topics.items()]

    def subscribers(self, topic):
        return self._topics[topic][1]


def test_stations_are_the_namespaces_of_robot_nodes():
    from gateway.rules.lease import glob_group
    from gateway.rules.stations import find_stations
    stamped = 'geometry_msgs/msg/TwistStamped'
    graph = Graph({
        '/robot1/cmd_vel': (TWIST, ['/robot1/base_controller']),
        '/robot2/diff_drive/cmd_vel': (stamped, ['/robot2/diff_drive/controller']),
        '/turtle1/cmd_vel': (TWIST, ['/turtlesim']),             # a root node: not a station
        '/lease/cmd_vel': (TWIST, ['/rosgate']),                  # a client's topic, watched through the gateway
        '/robot3/status': ('std_msgs/msg/String', ['/robot3/monitor']),   # not a velocity topic
        '/other/cmd_vel': (TWIST, ['/robot1/base_controller']),   # outside the node's namespace
    })
    assert find_stations(graph, frozenset({TWIST, stamped})) == ('/robot1', '/robot2')
    assert glob_group('/turtle1/*') == '/turtle1' and glob_group('/arm_*') == '/arm_*'
