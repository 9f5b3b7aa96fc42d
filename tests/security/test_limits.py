"""Name globs on every op and in rosapi, origins globs, frame size, per-client caps and op floods."""

from __future__ import annotations

import time

import pytest
from websockets.exceptions import InvalidStatus

from tests.support.wsclient import Client

FIB = 'example_interfaces/action/Fibonacci'


@pytest.fixture(scope='module')
def globbed(launch):
    return launch('--topics-glob', "['/open/*', '/pubonly/*', '/subonly/*']",
                  '--topics-pub-glob', "['/open/*', '/pubonly/*']",
                  '--topics-sub-glob', "['/open/*', '/subonly/*']",
                  '--services-glob', "['/rosapi/*', '/add_two_ints']",
                  '--actions-glob', "['/open/*']",
                  '--params-glob', "['/add_two_ints_server:*']",
                  '--allowed-origins', "['https://*.school.example']")


@pytest.fixture(scope='module')
def limited(launch):
    return launch('--max-message-size', '4096', '--max-subscriptions', '3', '--max-publishers', '2',
                  '--max-pending-calls', '2', '--max-op-rate', '200')


def refused_for(c: Client, op: dict, needle: str = 'is not allowed') -> bool:
    status = c.refusal(op)
    if status is None:
        return False
    assert status['msg'].startswith(f"{op['op']} (id {op['id']}): ") and needle in status['msg'], status
    return True


def test_globs_refuse_every_op(globbed):
    with Client(globbed.ws_url) as c:
        string = 'std_msgs/msg/String'
        # /client_count exists (Int32) but is hidden: refused alike with or without a type
        for op in ({'op': 'subscribe', 'topic': '/client_count'},
                   {'op': 'subscribe', 'topic': '/secret/x', 'type': string},
                   {'op': 'advertise', 'topic': '/secret/x', 'type': string},
                   {'op': 'publish', 'topic': '/client_count', 'msg': {'data': 1}},
                   {'op': 'publish', 'topic': '/secret/y', 'msg': {'data': 'x'}},
                   {'op': 'subscribe', 'topic': '/pubonly/a', 'type': string},
                   {'op': 'publish', 'topic': '/subonly/a', 'msg': {'data': 'x'}, 'type': string},
                   {'op': 'advertise_service', 'service': '/secret/svc', 'type': 'std_srvs/srv/Trigger'},
                   {'op': 'advertise_action', 'action': '/secret/act', 'type': FIB}):
            op['id'] = c.next_id(op['op'])
            assert refused_for(c, op), op
        for op in ({'op': 'subscribe', 'topic': '/subonly/a', 'type': string},
                   {'op': 'advertise', 'topic': '/pubonly/a', 'type': string},
                   {'op': 'subscribe', 'topic': '/open/a', 'type': string},
                   {'op': 'advertise_action', 'action': '/open/act', 'type': FIB}):
            op['id'] = c.next_id(op['op'])
            assert not refused_for(c, op), op
        reply = c.call('/fibonacci/_action/get_result')
        assert reply['result'] is False and 'is not allowed' in reply['values']
        c.send({'op': 'send_action_goal', 'action': '/fibonacci', 'action_type': FIB, 'args': {'order': 2},
                'id': 'g'})
        result = c.expect(lambda m: m.get('op') == 'action_result' and m.get('id') == 'g')
        assert result['result'] is False and 'is not allowed' in result['values']
        assert c.call('/add_two_ints', {'a': 1, 'b': 1})['values'] == {'sum': 2}
        setp = c.call('/rosapi/set_param', {'name': '/fibonacci_action_server:step_interval', 'value': '2'})
        assert setp['result'] is False and 'not allowed' in setp['values']


def test_an_actions_glob_also_closes_the_actions_hidden_services_and_topics(launch):
    """Every service allowed, actions limited: a goal sent through /fibonacci/_action/send_goal, a
    cancel, or a look at its status is refused as send_action_goal is; an allowed action's are not."""
    gw = launch('--actions-glob', "['/open/*']")
    with Client(gw.ws_url) as c:
        for name in ('send_goal', 'cancel_goal', 'get_result'):
            reply = c.call(f'/fibonacci/_action/{name}')
            assert reply['result'] is False and 'is not allowed' in reply['values'], (name, reply)
        op = {'op': 'subscribe', 'topic': '/fibonacci/_action/status', 'id': c.next_id('subscribe')}
        assert refused_for(c, op), op
        assert c.call('/add_two_ints', {'a': 1, 'b': 2})['values'] == {'sum': 3}
        c.send({'op': 'advertise_action', 'action': '/open/act', 'type': FIB, 'id': 'adv'})
        op = {'op': 'subscribe', 'topic': '/open/act/_action/status', 'id': c.next_id('subscribe')}
        assert not refused_for(c, op), op


def test_globs_hide_in_rosapi(globbed):
    with Client(globbed.ws_url) as c:
        c.subscribe('/open/a', 'std_msgs/msg/String')

        def values(service, args=None):
            reply = c.call(f'/rosapi/{service}', args)
            assert reply['result'], reply
            return reply['values']

        topics = values('topics')['topics']
        assert '/open/a' in topics and '/client_count' not in topics
        assert values('topic_type', {'topic': '/client_count'})['type'] == ''
        assert '/client_count' not in values('topics_for_type', {'type': 'std_msgs/msg/Int32'})['topics']
        assert '/client_count' not in values('topics_and_raw_types')['topics']
        assert values('publishers', {'topic': '/client_count'})['publishers'] == []
        assert values('subscribers', {'topic': '/open/a'})['subscribers'] != []
        details = values('node_details', {'node': globbed.node})
        assert '/client_count' not in details['publishing'] and '/open/a' in details['subscribing']
        services = values('services')['services']
        assert '/add_two_ints' in services and not any(s.startswith('/fibonacci') for s in services)
        assert values('service_type', {'service': '/fibonacci/_action/get_result'})['type'] == ''
        assert values('service_providers', {'service': '/fibonacci/_action/get_result'})['providers'] == []
        assert values('action_servers')['action_servers'] == []
        assert values('action_type', {'action': '/fibonacci'})['type'] == ''
        names = values('get_param_names')['names']
        assert not any(n.startswith('/fibonacci_action_server') for n in names)
        hidden = c.call('/rosapi/get_param', {'name': '/fibonacci_action_server:step_interval'})
        assert hidden['result'] is False


def test_allowed_origins_glob(globbed):
    with Client(globbed.ws_url, origin='https://lab.school.example') as ok:
        assert ok.call('/rosapi/get_time')['result']
    for origin in ('https://school.example.evil.com', 'http://lab.school.example'):
        with pytest.raises(InvalidStatus) as info:
            Client(globbed.ws_url, origin=origin)
        assert info.value.response.status_code == 403


def test_oversized_frames_refused_server_serves_others(limited):
    with Client(limited.ws_url) as bystander, Client(limited.ws_url) as c:
        big = '{"op": "publish", "id": "big", "topic": "/open/x", "msg": {"data": "%s"}}' % ('x' * 5000)
        c.send(big)
        status = c.status()
        assert status['level'] == 'error' and 'exceeds max_message_size 4096' in status['msg']
        assert c.call('/rosapi/get_time')['result']          # still connected
        c.send('x' * (4 * 4096 + 1))                          # past the hard limit: closed with 1009
        assert c.closed_code() == 1009
        assert bystander.call('/add_two_ints', {'a': 1, 'b': 2})['values'] == {'sum': 3}


def test_caps_on_subscriptions_publishers_and_pending_calls(limited):
    with Client(limited.ws_url) as c:
        for i in range(3):
            c.subscribe(f'/cap/s{i}', 'std_msgs/msg/String')
        c.subscribe('/cap/s0', 'std_msgs/msg/String')   # the same topic again is no new subscription
        assert refused_for(c, {'op': 'subscribe', 'topic': '/cap/s3', 'type': 'std_msgs/msg/String',
                               'id': 'sub4'}, '3 subscriptions')
        for i in range(2):
            assert c.refusal({'op': 'advertise', 'topic': f'/cap/p{i}', 'type': 'std_msgs/msg/String'}) is None
        assert refused_for(c, {'op': 'publish', 'topic': '/cap/p2', 'type': 'std_msgs/msg/String',
                               'msg': {'data': 'x'}, 'id': 'pub3'}, 'advertises 2 topics')
        for i in range(2):   # goals that stay pending (one Fibonacci step a second)
            c.send({'op': 'send_action_goal', 'action': '/fibonacci', 'action_type': FIB,
                    'args': {'order': 40}, 'id': f'goal{i}'})
        c.send({'op': 'send_action_goal', 'action': '/fibonacci', 'action_type': FIB, 'args': {'order': 4},
                'id': 'goal2'})
        result = c.expect(lambda m: m.get('op') == 'action_result' and m.get('id') == 'goal2')
        assert result['result'] is False and '2 calls and goals pending' in result['values']
        assert 'send_action_goal (id goal2)' in c.status('goal2')['msg']


@pytest.fixture(scope='module')
def trickle(launch):
    """One op per 100 s: a flood is a flood however slowly this machine lets the test send it."""
    return launch('--max-op-rate', '0.01')


def test_op_flood_refused_and_others_served(trickle):
    # the budget is one op; each op over it is refused, and the 101st refusal in a row closes
    # the connection (threshold: max(100, rate)), so exactly 102 ops end it whatever the timing
    with Client(trickle.ws_url) as bystander, Client(trickle.ws_url) as flooder:
        for i in range(102):
            flooder.send({'op': 'unsubscribe', 'topic': '/flood', 'id': f'f{i}'})
        code = flooder.closed_code(timeout=30)
        refusals = [m for m in flooder.seen if 'op rate limit' in m.get('msg', '')]
        assert code == 1008
        assert [m['id'] for m in refusals] == [f'f{i}' for i in range(1, 101)]
        assert all(m['msg'].startswith(f"unsubscribe (id {m['id']}): ") for m in refusals)
        assert bystander.call('/add_two_ints', {'a': 2, 'b': 2})['values'] == {'sum': 4}
    with Client(trickle.ws_url) as again:   # the limit is per client: a new connection is served
        assert again.call('/rosapi/get_time')['result']


def test_flood_below_the_close_threshold_keeps_connection(limited):
    with Client(limited.ws_url) as c:
        for i in range(300):
            c.send({'op': 'unsubscribe', 'topic': '/flood', 'id': f'f{i}'})
        assert 'op rate limit of 200 per second' in c.status('f299')['msg']
        deadline = time.monotonic() + 5
        while not c.call('/rosapi/get_time')['result']:   # the budget refills on the same connection
            assert time.monotonic() < deadline
            time.sleep(0.05)
