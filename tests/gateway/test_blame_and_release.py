"""In-process: the one blame classifier, and release next to creation in subscribe.

These drive a real ClientSession on a real Gateway with the sim backend, with ops that the
protocol layer would refuse (so they cannot come over the wire): that is how a bug looks.
"""

from __future__ import annotations

import logging

import orjson

from gateway.backends.sim import SimBackend
from gateway.capabilities import topics
from gateway.core import Gateway
from gateway.session import ClientSession
from gateway.settings import Settings
from protocol.errors import ProtocolError
from protocol.ops import Subscribe


async def _session():
    backend = SimBackend(demo=False)
    await backend.start()
    gateway = Gateway(Settings(), backend)
    sent: list[dict] = []
    session = ClientSession(gateway, lambda payload, binary: sent.append(orjson.loads(payload)),
                            lambda code, reason: None)
    session.open()
    return backend, gateway, session, sent


async def test_a_subscribe_that_fails_half_way_leaves_nothing_behind():
    backend, gateway, session, sent = await _session()
    topic = '/release/test'
    op = Subscribe(topic=topic, type='std_msgs/msg/String', id='ov', throttle_rate=10**400)
    try:
        topics.subscribe(session, op)
    except OverflowError:
        pass
    assert topic not in gateway.fanouts and topic not in session.subscriptions
    assert backend.subscribers(topic) == []
    # a good subscribe after it works, and closing releases it
    topics.subscribe(session, Subscribe(topic=topic, type='std_msgs/msg/String', id='ok'))
    assert list(gateway.fanouts[topic].subscribers[session.id].options) == ['ok']
    assert backend.subscribers(topic) != []
    session.close()
    assert topic not in gateway.fanouts and backend.subscribers(topic) == []
    await backend.stop()


async def test_our_value_errors_are_bugs_logged_with_a_traceback(caplog):
    backend, gateway, session, sent = await _session()
    with caplog.at_level(logging.ERROR, logger='rosgate'):
        try:
            int('not a number')
        except ValueError as e:
            session.report('subscribe', 'v1', e)
    assert sent[-1]['id'] == 'v1' and 'internal error (ValueError)' in sent[-1]['msg']
    assert caplog.records and caplog.records[-1].exc_info is not None
    caplog.clear()
    session.report('subscribe', 'p1', ProtocolError("field 'topic' must be a string", op='subscribe'))
    assert sent[-1] == {'op': 'status', 'level': 'error', 'id': 'p1',
                        'msg': "subscribe (id p1): field 'topic' must be a string"}
    assert not caplog.records
    session.close()
    await backend.stop()
