"""A throttled MarkerArray subscription gets every change, merged (gateway/bridge/markers.py)."""

from __future__ import annotations

import time

from gateway.bridge.markers import merge
from tests.support.rawclient import Raw

ADD, DELETE, DELETEALL = 0, 2, 3
MARKERS = 'visualization_msgs/msg/MarkerArray'


def m(ns, id, action=ADD, x=0.0):
    return {'ns': ns, 'id': id, 'action': action, 'pose': {'position': {'x': x}}}


def test_merge_keeps_the_newest_of_each_marker_and_every_other_change():
    a = {'markers': [m('robots', 1, x=1.0), m('pen', 1), m('pen', 2)]}
    b = {'markers': [m('robots', 1, x=2.0), m('pen', 3), m('scan', 5, DELETE)]}
    got = merge(a, b)['markers']
    assert [(k['ns'], k['id']) for k in got] == [('pen', 1), ('pen', 2), ('robots', 1), ('pen', 3), ('scan', 5)]
    assert got[2]['pose']['position']['x'] == 2.0
    assert merge(None, b) is b


def test_deleteall_drops_what_came_before_in_its_namespace_only():
    a = {'markers': [m('robots', 1), m('pen', 1), m('pen', 2)]}
    b = {'markers': [m('pen', 0, DELETEALL), m('pen', 7)]}
    got = merge(a, b)['markers']
    assert [(k['ns'], k['id'], k['action']) for k in got] == [
        ('robots', 1, ADD), ('pen', 0, DELETEALL), ('pen', 7, ADD)]
    everything = merge(a, {'markers': [m('', 0, DELETEALL)]})['markers']
    assert [k['action'] for k in everything] == [DELETEALL]


def test_a_throttled_marker_subscription_loses_no_increment(gateway):
    """Ten increments within a throttle period arrive as one merged message holding all ten."""
    topic = '/merge_test/markers'
    with_pub, viewer = Raw(gateway.ws_url), Raw(gateway.ws_url)
    viewer.send({'op': 'subscribe', 'topic': topic, 'type': MARKERS, 'throttle_rate': 1000, 'queue_length': 1})
    with_pub.send({'op': 'advertise', 'topic': topic, 'type': MARKERS})
    viewer.call('/rosapi/get_time')
    with_pub.call('/rosapi/get_time')
    for i in range(11):
        with_pub.send({'op': 'publish', 'topic': topic, 'msg': {'markers': [
            {'ns': 'pen', 'id': i, 'action': ADD}, {'ns': 'robots', 'id': 1, 'action': ADD, 'text': f'r{i}'}]}})
        time.sleep(0.01)
    got = []
    while sum(len(x['msg']['markers']) for x in got) < 12:
        got.append(viewer.expect(lambda x: x.get('op') == 'publish', timeout=5))
    assert len(got) == 2                       # the first at once, the rest merged at the period's end
    pens = sorted(k['id'] for x in got for k in x['msg']['markers'] if k['ns'] == 'pen')
    assert pens == list(range(11))
    assert got[-1]['msg']['markers'][-1]['text'] == 'r10'
    assert sum(1 for k in got[-1]['msg']['markers'] if k['ns'] == 'robots') == 1
