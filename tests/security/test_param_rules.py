"""Parameters of a node from outside, against --auth --fleet 2: through the node's own rcl_interfaces
services (what /inspect and `ros2 param` use) and through rosapi. A viewer reads and may not set
(a status names the op, its id and why); a student (operator) sets only the nodes of the station she
owns; an admin sets any. The gateway judges each call, whatever a page shows."""

from __future__ import annotations

import pytest

from tests.support.auth import TOKENS
from tests.support.wsclient import Client

SET = 'rcl_interfaces/srv/SetParameters'


@pytest.fixture(scope='module')
def school(launch, tokens_file):
    return launch('--robot', 'turtlesim', '--fleet', '2', '--auth', tokens_file)


@pytest.fixture
def people(school):
    clients = {who: Client(school.ws_url, TOKENS[who]) for who in TOKENS}
    yield clients
    for c in clients.values():
        c.close()


def red(value: int) -> dict:
    return {'parameters': [{'name': 'background_r', 'value': {'type': 2, 'integer_value': value}}]}


def background_r(client: Client, ns: str) -> int:
    reply = client.call(f'{ns}/turtlesim/get_parameters', {'names': ['background_r']})
    assert reply['result'] is True, reply
    return reply['values']['values'][0]['integer_value']


def set_op(service: str, args: dict, id: str) -> dict:
    return {'op': 'call_service', 'service': service, 'args': args, 'id': id, 'type': SET}


def test_a_viewer_reads_parameters_and_may_not_set_them(people):
    viewer = people['viewer']
    listed = viewer.call('/s01/turtlesim/list_parameters', {'prefixes': [], 'depth': 0})
    assert listed['result'] is True and 'background_r' in listed['values']['result']['names'], listed
    described = viewer.call('/s01/turtlesim/describe_parameters', {'names': ['background_r']})
    assert described['values']['descriptors'][0]['type'] == 2
    before = background_r(viewer, '/s01')

    status = viewer.refusal(set_op('/s01/turtlesim/set_parameters', red(7), 'viewer-set'))
    assert status is not None and status['id'] == 'viewer-set', status
    assert 'call_service' in status['msg'] and 'role viewer may not change parameters' in status['msg'], status
    atomic = viewer.refusal({'op': 'call_service', 'service': '/s01/turtlesim/set_parameters_atomically',
                             'args': red(7), 'id': 'viewer-atomic'})
    assert atomic is not None and 'viewer' in atomic['msg']
    rosapi = viewer.call('/rosapi/set_param', {'name': '/s01/turtlesim:background_r', 'value': '7'})
    assert rosapi['result'] is False
    assert background_r(viewer, '/s01') == before


def test_a_student_sets_her_own_stations_nodes_only(people):
    alice, bob = people['operator'], people['operator2']
    claimed = alice.call('/fleet/claim')
    assert claimed['values']['success'] is True, claimed
    mine = claimed['values']['message']
    theirs = '/s02' if mine == '/s01' else '/s01'
    others = background_r(alice, theirs)

    done = alice.call(f'{mine}/turtlesim/set_parameters', red(11))
    assert done['result'] is True and done['values']['results'] == [{'successful': True, 'reason': ''}], done
    assert background_r(alice, mine) == 11

    status = alice.refusal(set_op(f'{theirs}/turtlesim/set_parameters', red(12), 'alice-other'))
    assert status is not None and status['id'] == 'alice-other', status
    assert f'{theirs}/turtlesim is not in a station of yours' in status['msg'], status
    # rosapi's way judges the parameter's node the same
    assert alice.call('/rosapi/set_param', {'name': f'{theirs}/turtlesim:background_r', 'value': '12'})['result'] is False
    assert alice.call('/rosapi/set_param', {'name': f'{mine}/turtlesim:background_r', 'value': '13'})['result'] is True
    assert background_r(alice, mine) == 13
    assert background_r(alice, theirs) == others

    # bob owns no station: alice's is not his either
    status = bob.refusal(set_op(f'{mine}/turtlesim/set_parameters', red(14), 'bob-alices'))
    assert status is not None and 'not in a station of yours' in status['msg'], status
    assert background_r(bob, mine) == 13


def test_an_admin_sets_any_nodes_parameters(people):
    admin = people['admin']
    for ns, value in (('/s01', 21), ('/s02', 22)):
        done = admin.call(f'{ns}/turtlesim/set_parameters', red(value))
        assert done['values']['results'][0]['successful'] is True, done
        assert background_r(admin, ns) == value
    wrong = admin.call('/s01/turtlesim/set_parameters',
                       {'parameters': [{'name': 'background_r', 'value': {'type': 4, 'string_value': 'red'}}]})
    assert wrong['result'] is True and not wrong['values']['results'][0]['successful']   # the node refuses a string
    assert background_r(admin, '/s01') == 21
