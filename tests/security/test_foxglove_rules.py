"""The Foxglove face obeys the rules of a rosbridge client, tried from outside as an attacker would:
a foreign Origin, no token (shown nothing, closed at --auth-timeout), the driver lease another
client holds, the velocity clamp, the gateway's own topics, the caps, parameters for admins only;
and a rosbridge client offering some other subprotocol still speaks rosbridge."""

from __future__ import annotations

import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus

from tests.support.auth import TOKENS
from tests.support.foxglove import Fox, read_twist, twist_cdr
from tests.support.wsclient import TWIST, Client, twist

CMD = '/turtle1/cmd_vel'


@pytest.fixture(scope='module')
def gw(launch, tokens_file):
    return launch('--robot', 'turtlesim', '--history', 'none', '--auth', tokens_file, '--exclusive-control',
                  '--max-linear', '0.5', '--max-subscriptions', '3', '--cmd-timeout', '0', '--auth-timeout', '2')


def test_a_foreign_origin_is_refused_at_the_upgrade(gw):
    with pytest.raises(InvalidStatus) as refused:
        Fox(gw.ws_url, TOKENS['operator'], origin='https://app.evil.example')
    assert refused.value.response.status_code == 403


def test_without_a_token_nothing_is_shown_and_the_socket_is_closed_in_time(gw):
    fox = Fox(gw.ws_url)
    try:
        assert fox.subprotocol == 'foxglove.websocket.v1'
        fox.status('not authenticated: connect with ?token=')
        fox.expect(lambda m: isinstance(m, dict) and m.get('op') == 'advertise')
        assert fox.channels == {} and fox.services == {}
        fox.send({'op': 'subscribeConnectionGraph'})
        assert 'not authenticated' in fox.status('subscribeConnectionGraph')['message']
        fox.send({'op': 'getParameters', 'parameterNames': [], 'id': 'p'})
        assert 'not authenticated' in fox.status('getParameters')['message']
        fox.status('not authenticated within 2 s; closing the connection (1008)')
        with pytest.raises(ConnectionClosed) as closed:
            while True:
                fox.recv(10)
        assert closed.value.rcvd.code == 1008
    finally:
        fox.close()


def test_a_wrong_token_is_named_and_shows_nothing(gw):
    fox = Fox(gw.ws_url, 'not-a-token')
    try:
        assert 'the token given' in fox.status('not authenticated')['message']
        fox.expect(lambda m: isinstance(m, dict) and m.get('op') == 'advertise')
        assert fox.channels == {}
    finally:
        fox.close()


def test_the_lease_holder_drives_and_a_foxglove_client_is_refused_until_it_leaves(gw):
    with Client(gw.ws_url, TOKENS['viewer']) as watcher, Client(gw.ws_url, TOKENS['operator']) as alice:
        watcher.subscribe(CMD, TWIST)
        alice.publish(CMD, twist(0.3), TWIST)
        assert watcher.next_message(CMD) == twist(0.3)
        bob = Fox(gw.ws_url, TOKENS['operator2'])
        try:
            cmd = bob.advertise(CMD, TWIST)
            bob.publish(cmd, twist_cdr(0.4))
            refusal = bob.status('messageData')
            assert refusal['level'] == 2 and 'alice (client' in refusal['message'] and 'is driving' in refusal['message']
            alice.close()
            # alice gone: her lease goes with her (her last command is zeroed), and bob's command passes
            watcher.next_message(CMD, lambda m: m['linear']['x'] == 0)
            bob.publish(cmd, twist_cdr(0.4))
            assert watcher.next_message(CMD, lambda m: m['linear']['x'] != 0)['linear']['x'] == pytest.approx(0.4)
            bob.publish(cmd, twist_cdr(0.0))
            watcher.next_message(CMD, lambda m: m['linear']['x'] == 0)
        finally:
            bob.close()


def test_commands_are_clamped_and_the_gateways_own_topics_are_not_a_clients(gw):
    admin = Fox(gw.ws_url, TOKENS['admin'])
    try:
        sub = admin.subscribe(CMD)
        cmd = admin.advertise(CMD, TWIST)
        admin.publish(cmd, twist_cdr(3.0))
        x, _ = read_twist(admin.message(sub))
        assert x == pytest.approx(0.5)   # --max-linear
        admin.publish(cmd, twist_cdr(0.0))
        admin.advertise('/rosgate/driver', 'std_msgs/msg/String')
        assert '/rosgate/driver is not allowed for publish' in admin.status('advertise')['message']
    finally:
        admin.close()


def test_the_subscription_cap_holds(gw):
    fox = Fox(gw.ws_url, TOKENS['viewer'])
    try:
        topics = [t for t in ('/turtle1/pose', '/turtle1/color_sensor', CMD, '/rosout')]
        for topic in topics:
            fox.subscribe(topic)
        assert 'already has 3 subscriptions (--max-subscriptions)' in fox.status('subscribe')['message']
    finally:
        fox.close()


def test_parameters_are_read_by_anyone_and_set_by_admins(gw):
    """The parameter rule of rosbridge clients (rules/access.py): an operator sets only her own station's nodes."""
    viewer, operator, admin = (Fox(gw.ws_url, TOKENS[r]) for r in ('viewer', 'operator', 'admin'))
    try:
        viewer.send({'op': 'getParameters', 'parameterNames': ['/turtlesim.background_g'], 'id': 'g'})
        got = viewer.expect(lambda m: isinstance(m, dict) and m.get('id') == 'g')
        assert got['op'] == 'parameterValues' and got['parameters'][0]['name'] == '/turtlesim.background_g'
        value = got['parameters'][0]['value']
        operator.send({'op': 'setParameters', 'parameters': [{'name': '/turtlesim.background_g', 'value': 1}], 'id': 's'})
        assert '/turtlesim is not in a station of yours' in operator.status('setParameters')['message']
        admin.send({'op': 'setParameters', 'parameters': [{'name': '/turtlesim.background_g', 'value': value}],
                    'id': 's'})
        assert admin.expect(lambda m: isinstance(m, dict) and m.get('id') == 's')['parameters'][0]['value'] == value
    finally:
        for fox in (viewer, operator, admin):
            fox.close()


def test_a_client_offering_another_subprotocol_speaks_rosbridge(gw):
    with Client(gw.ws_url, TOKENS['viewer'], subprotocols=['rosbridge.v2', 'json']) as ros:
        assert ros.ws.subprotocol is None
        assert 'sec' in ros.call('/rosapi/get_time')['values']['time']


def test_a_client_cannot_pile_up_channels_on_one_topic(gw):
    fox = Fox(gw.ws_url, TOKENS['operator'])
    try:
        channels = [{'id': i, 'topic': '/fox/pile', 'encoding': 'cdr', 'schemaName': 'std_msgs/msg/String'}
                    for i in range(1, 1002)]
        fox.send({'op': 'advertise', 'channels': channels})
        refusal = fox.status('(id 1001)')
        assert refusal['message'] == 'advertise (id 1001): this client already has 1000 channels (--max-publishers)'
    finally:
        fox.close()


def test_the_sdk_subprotocol_is_the_same_wire_and_playback_control_is_refused(gw):
    fox = Fox(gw.ws_url, TOKENS['viewer'], subprotocols=('foxglove.sdk.v1', 'foxglove.websocket.v1'))
    try:
        assert fox.subprotocol == 'foxglove.sdk.v1'
        info = fox.expect(lambda m: isinstance(m, dict) and m.get('op') == 'serverInfo')
        assert info['metadata']['ROS_DISTRO'] == 'jazzy'
        sid = fox.subscribe('/turtle1/pose')
        assert len(fox.message(sid)) == 4 + 5 * 4   # turtlesim/msg/Pose: five float32
        fox.ws.send(b'\x03' + b'\x00' * 16)   # foxglove.sdk.v1's playback control request
        assert fox.status('playbackControlRequest')['message'].endswith('it has no playbackControl capability')
        assert len(fox.message(sid)) == 24   # and the connection carries on
    finally:
        fox.close()
