"""In-process: the one blame classifier, and release next to creation in subscribe.

These drive a real ClientSession on a real Gateway with the sim backend, with ops that the
protocol layer would refuse (so they cannot come over the wire): that is how a bug looks.
"""

from __future__ import annotations

import logging

import orjson

from gateway.backends.sim import SimBackend
from gateway.bridge.capabilities import topics
from gateway.bridge.gateway import Gateway
from gateway.bridge.session import ClientSession
from gateway.settings import Settings
from protocol.errors import ProtocolError
from protocol.ops import Subscribe


async def _session():
    backend = SimBackend(demo=False)
    await backend.start()
    gateway = Gateway(Settings(), backend)
    sent: list[dict] = []
    session = ClientSession(gateway, lambda payload, binary: sent.append(orjson.loads(payload)),
                            lambda frames: sent.extend(orjson.loads(payload) for payload, _ in frames),
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


async def test_a_sim_action_logs_a_refused_goal_as_a_warning_and_its_own_bug_with_a_traceback(caplog):
    from gateway.backends.base import STATUS_ABORTED, BackendError

    backend = SimBackend(demo=False)
    await backend.start()
    node = backend.graph.node('blame_actions')

    async def execute(goal):
        if goal.request['order'] < 0:
            raise BackendError('order must not be negative')   # the client's mistake
        return {'sequence': [1 // 0]}                           # a bug of the server

    node.create_simple_action_server('/blame/fib', 'example_interfaces/action/Fibonacci', execute)
    try:
        for order, level, traceback in ((-1, logging.WARNING, False), (3, logging.ERROR, True)):
            caplog.clear()
            with caplog.at_level(logging.WARNING, logger='rosgate'):
                goal = await backend.graph.send_goal('/blame/fib', 'example_interfaces/action/Fibonacci',
                                                    {'order': order}, None)
                result = await goal.result()
            assert result.status == STATUS_ABORTED
            [record] = [r for r in caplog.records if '/blame/fib' in r.getMessage()]
            assert record.levelno == level and (record.exc_info is not None) == traceback, record
    finally:
        node.destroy()
        await backend.stop()
