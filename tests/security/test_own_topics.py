"""The gateway's own topics (/rosgate/driver, /rosgate/runs/ID/...) carry only what the gateway
says: a client's publish or advertise there is refused and a viewer never sees it; and a publish
whose type is not the one its client advertised is refused, naming op and id, and delivers
nothing."""

from __future__ import annotations

import json

from tests.support.auth import TOKENS
from tests.support.http import api
from tests.support.wait import wait_for
from tests.support.wsclient import Client

STRING = 'std_msgs/msg/String'


def test_a_client_cannot_speak_for_the_gateway(launch, tokens_file, tmp_path):
    gw = launch('--robot', 'turtlesim', '--fleet', '3', '--auth', tokens_file, '--allow-runs', '--exclusive-control',
                '--runs-dir', str(tmp_path / 'runs'))
    status, body = api(gw, 'POST', '/api/runs', {'source': 'import time\ntime.sleep(60)\n', 'name': 'real'},
                       TOKENS['operator'])
    assert status == 201, body
    run = body['id']
    wait_for(lambda: api(gw, 'GET', f'/api/runs/{run}', token=TOKENS['admin'])[1]['state'] == 'running', 30)
    own = ['/rosgate/driver', f'/rosgate/runs/{run}/output', f'/rosgate/runs/{run}/state']
    try:
        with Client(gw.ws_url, TOKENS['admin']) as viewer, Client(gw.ws_url, TOKENS['operator']) as alice, \
                Client(gw.ws_url, TOKENS['admin']) as teacher:
            for topic in own:
                viewer.subscribe(topic, STRING)
            viewer.sync()
            for who in (alice, teacher):
                for topic in own:
                    fake = json.dumps({'driver': {'name': 'FAKE'}, 'state': 'FAKE', 'line': 'FAKE'})
                    refused = who.refusal({'op': 'publish', 'topic': topic, 'type': STRING, 'msg': {'data': fake}})
                    assert refused and topic in refused['msg'], (topic, refused)
                    refused = who.refusal({'op': 'advertise', 'topic': topic, 'type': STRING})
                    assert refused and refused['msg'].startswith('advertise') and topic in refused['msg'], (topic, refused)
                    refused = who.refusal({'op': 'publish', 'topic': topic, 'msg': {'data': 'FAKE'}})   # no type
                    assert refused, topic
            viewer.sync()   # anything the fakes had reached it with would be before this reply
            got = [m for m in viewer.seen if m.get('op') == 'publish']
            assert got and not [m for m in got if 'FAKE' in json.dumps(m)], got
    finally:
        api(gw, 'DELETE', f'/api/runs/{run}', token=TOKENS['operator'])


def test_a_publish_of_another_type_than_advertised_is_refused(gateway):
    with Client(gateway.ws_url) as viewer, Client(gateway.ws_url) as talker:
        viewer.subscribe('/typed', STRING)
        assert talker.refusal({'op': 'advertise', 'topic': '/typed', 'type': STRING}) is None
        # {} is a valid message of either type: nothing but the check stops it going out as a String
        refused = talker.refusal({'op': 'publish', 'id': 'mismatch-1', 'topic': '/typed',
                                  'type': 'std_msgs/msg/Int32', 'msg': {}})
        assert refused and refused['id'] == 'mismatch-1' and 'publish' in refused['msg'], refused
        assert 'std_msgs/msg/String' in refused['msg'] and 'Int32' in refused['msg'], refused
        # the same type, short or long, goes through; so does one without a type
        assert talker.refusal({'op': 'publish', 'topic': '/typed', 'type': 'std_msgs/String', 'msg': {'data': 'a'}}) is None
        assert talker.refusal({'op': 'publish', 'topic': '/typed', 'msg': {'data': 'b'}}) is None
        assert viewer.next_message('/typed') == {'data': 'a'}
        assert viewer.next_message('/typed') == {'data': 'b'}
        viewer.sync()
        assert not [m for m in viewer.seen if m.get('op') == 'publish'], viewer.seen   # nothing of the Int32
