"""Slots booked ahead (--booking, gateway/rules/bookings.py): the API's answers, the station being
its booker's during her slot, and the gateway itself ending the slot with no page acting, on the
flags of the lab: --fleet 2 --auth --exclusive-control --allow-runs --booking --slot-minutes 0.25
--station-reset reset. Real processes: the gateway, roslibpy and raw rosbridge clients, a real
robot-side run."""

from __future__ import annotations

import datetime
import json
import queue
import time

import pytest
import roslibpy

from tests.support.auth import TOKENS
from tests.support.http import api, http
from tests.support.ros import client as connect
from tests.support.runs import ENDED, program, state_of
from tests.support.wait import wait_for
from tests.support.wsclient import Client

TWIST = 'geometry_msgs/msg/Twist'
POSE = 'turtlesim/msg/Pose'
START = 5.544445   # where turtlesim puts turtle1, and puts it back on reset
LAB = ('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--allow-runs', '--booking',
       '--slot-minutes', '0.25', '--station-reset', 'reset')


@pytest.fixture(scope='module')
def lab(launch, tokens_file, tmp_path_factory):
    return launch(*LAB, '--auth', tokens_file, '--runs-dir', str(tmp_path_factory.mktemp('runs')))


def book(gw, who: str, station: str, start: float, end: float):
    return api(gw, 'POST', '/api/bookings', {'station': station, 'start': start, 'end': end}, token=TOKENS[who])


def stations_info(ros) -> dict:
    box = []
    t = roslibpy.Topic(ros, '/rosgate/stations', 'std_msgs/msg/String')
    t.subscribe(lambda m: box.append(json.loads(m['data'])))
    wait_for(lambda: box, 10)
    t.unsubscribe()
    return box[-1]


def twist(x: float) -> dict:
    return {'linear': {'x': x, 'y': 0.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}


def drive(c: Client, ns: str, x: float = 1.0) -> dict | None:
    """One velocity command; the status error that refused it (None: it passed)."""
    return c.refusal({'op': 'publish', 'topic': f'{ns}/turtle1/cmd_vel', 'type': TWIST, 'msg': twist(x)})


class Poses:
    """Every pose of a station's turtle with the wall-clock time it came."""

    def __init__(self, ros, ns: str):
        self.q: queue.Queue = queue.Queue()
        self.seen: list[tuple[float, dict]] = []
        roslibpy.Topic(ros, f'{ns}/turtle1/pose', POSE).subscribe(lambda m: self.q.put((time.time(), m)))

    def pump(self) -> list[tuple[float, dict]]:
        while True:
            try:
                self.seen.append(self.q.get_nowait())
            except queue.Empty:
                return self.seen

    def last(self) -> dict | None:
        seen = self.pump()
        return seen[-1][1] if seen else None

    def wait(self, predicate, timeout: float = 10) -> dict:
        return wait_for(lambda: (lambda p: p if p is not None and predicate(p) else None)(self.last()), timeout)


def at_start(p: dict) -> bool:
    return abs(p['x'] - START) < 1e-3 and abs(p['y'] - START) < 1e-3


def test_a_booking_is_answered_201_an_overlap_409_a_viewer_403(lab):
    t = time.time() + 600
    status, mine = book(lab, 'operator', '/s02', t, t + 10)
    assert status == 201, mine
    assert mine['station'] == '/s02' and mine['name'] == 'alice' and mine['mine'] is True
    status, body = book(lab, 'operator2', '/s02', t + 5, t + 12)
    assert status == 409 and 'alice' in body['error'], body
    assert book(lab, 'viewer', '/s01', t, t + 5)[0] == 403
    assert book(lab, 'operator2', '/s02', t + 10, t + 15)[0] == 201   # touching, not overlapping
    assert book(lab, 'operator', '/s01', t + 2, t + 8)[0] == 409       # alice: one station at a time
    # the teacher books for a student; a student may not book for another
    for_bob = {'station': '/s01', 'start': t + 30, 'end': t + 40, 'for': 'bob'}
    assert api(lab, 'POST', '/api/bookings', for_bob, token=TOKENS['operator'])[0] == 403
    status, made = api(lab, 'POST', '/api/bookings', for_bob, token=TOKENS['admin'])
    assert status == 201 and made['name'] == 'bob' and made['mine'] is False, made
    assert api(lab, 'GET', f'/api/bookings/{made["id"]}', token=TOKENS['operator2'])[1]['mine'] is True
    assert api(lab, 'DELETE', f'/api/bookings/{made["id"]}', token=TOKENS['operator2'])[0] == 200
    # bad slots say why
    status, body = book(lab, 'operator2', '/s01', t + 100, t + 120)
    assert status == 400 and '0.25 minutes' in body['error']
    assert book(lab, 'operator2', '/s09', t, t + 5)[0] == 404
    assert book(lab, 'operator2', '/s01', t + 5, t)[0] == 400
    assert api(lab, 'POST', '/api/bookings', {'station': '/s01', 'start': 'soon', 'end': t}, token=TOKENS['operator2'])[0] == 400
    assert api(lab, 'POST', '/api/bookings', {'station': '/s01', 'start': t, 'end': t + 5})[0] == 401
    # everyone who may read sees the timetable; only the booker's own are "mine"
    status, listed = api(lab, 'GET', f'/api/bookings?station=/s02&from={t - 1}&to={t + 20}', token=TOKENS['viewer'])
    assert status == 200 and [b['name'] for b in listed['bookings']] == ['alice', 'bob']
    assert not any(b['mine'] for b in listed['bookings']) and listed['slot'] == 15
    assert api(lab, 'GET', f'/api/bookings?station=/s02&from={t + 200}', token=TOKENS['viewer'])[1]['bookings'] == []


def test_delete_is_for_the_booker_or_an_admin(lab):
    t = time.time() + 900
    _, b = book(lab, 'operator', '/s01', t, t + 10)
    assert api(lab, 'DELETE', f'/api/bookings/{b["id"]}', token=TOKENS['operator2'])[0] == 403
    assert api(lab, 'DELETE', f'/api/bookings/{b["id"]}', token=TOKENS['viewer'])[0] == 403
    assert api(lab, 'DELETE', f'/api/bookings/{b["id"]}', token=TOKENS['operator'])[0] == 200
    assert api(lab, 'GET', f'/api/bookings/{b["id"]}', token=TOKENS['operator'])[0] == 404
    _, b = book(lab, 'operator', '/s01', t, t + 10)                    # the time is free again
    assert api(lab, 'DELETE', f'/api/bookings/{b["id"]}', token=TOKENS['admin'])[0] == 200
    assert api(lab, 'DELETE', '/api/bookings/999999', token=TOKENS['admin'])[0] == 404
    assert api(lab, 'DELETE', '/api/bookings/nope', token=TOKENS['admin'])[0] == 404


def test_quotas_refuse_with_429(lab):
    limits = api(lab, 'GET', '/api/bookings', token=TOKENS['operator2'])[1]['limits']
    noon = datetime.datetime.combine(datetime.date.today() + datetime.timedelta(days=2), datetime.time(12))
    t = noon.timestamp()
    for i in range(limits['per_day']):
        status, body = book(lab, 'operator2', '/s01', t + 20 * i, t + 20 * i + 10)
        assert status == 201, body
    status, body = book(lab, 'operator2', '/s01', t + 3000, t + 3010)
    assert status == 429 and 'a day' in body['error'], body
    status, body = book(lab, 'operator2', '/s01', t + 86400, t + 86410)     # another day is fine
    assert status == 201, body
    far = time.time() + limits['ahead'] + 86400
    status, body = book(lab, 'operator', '/s01', far, far + 10)
    assert status == 429 and 'ahead' in body['error'], body
    assert book(lab, 'admin', '/s01', t + 3000, t + 3010)[0] == 201         # the teacher has no quota


def test_calendar_feed_lists_a_persons_own_slots(lab):
    t = time.time() + 1200
    _, hers = book(lab, 'operator', '/s02', t, t + 10)
    feed = '/api/bookings.ics?token='
    res = http(lab, feed + TOKENS['operator'])
    assert res.status == 200 and res.headers['Content-Type'].startswith('text/calendar')
    text = res.body.decode()
    stamp = datetime.datetime.fromtimestamp(t, datetime.timezone.utc).strftime('%Y%m%dT%H%M%SZ')
    assert text.startswith('BEGIN:VCALENDAR') and f'UID:booking-{hers["id"]}@' in text
    assert f'DTSTART:{stamp}' in text and 'LOCATION:/s02' in text
    res = http(lab, feed + TOKENS['operator2'])    # bob's: his own only
    assert res.status == 200 and f'UID:booking-{hers["id"]}@' not in res.body.decode()
    res = http(lab, feed + TOKENS['admin'])        # the teacher's: everyone's
    assert res.status == 200 and f'UID:booking-{hers["id"]}@' in res.body.decode()


def test_the_slot_is_the_bookers_and_the_gateway_ends_it(lab):
    """Alice's slot, then bob's on /s01: bob cannot move the turtle during hers; alice drives
    without Take and starts a run; at her slot's end, with no page acting, the turtle stops
    within 1 s and is back at its start pose, her run ends, her commands are refused, and bob
    drives without Take."""
    with connect(lab, TOKENS['viewer']) as watcher, Client(lab.ws_url, TOKENS['operator']) as alice, \
            Client(lab.ws_url, TOKENS['operator2']) as bob:
        poses = Poses(watcher, '/s01')
        poses.wait(lambda p: True)
        begin = time.time() + 2
        status, hers = book(lab, 'operator', '/s01', begin, begin + 15)
        assert status == 201, hers
        status, his = book(lab, 'operator2', '/s01', begin + 15, begin + 30)
        assert status == 201, his
        wait_for(lambda: stations_info(watcher)['owners'].get('/s01', {}).get('name') == 'alice', 10, 0.1)
        info = stations_info(watcher)
        assert info['booked']['/s01']['name'] == 'alice' and info['next']['/s01']['name'] == 'bob'

        # during her slot bob's commands are refused and the turtle does not move
        for _ in range(3):
            refusal = drive(bob, '/s01')
            assert refusal is not None and 'alice' in refusal['msg'], refusal
        refused_at = time.time()
        answer = bob.call('/s01/fleet/claim')['values']
        assert answer['success'] is False and "alice's station until" in answer['message'], answer
        wait_for(lambda: len([1 for at, _ in poses.pump() if at > refused_at]) >= 10, 10)
        assert all(at_start(p) and p['linear_velocity'] == 0 for at, p in poses.pump() if at > refused_at)

        # alice drives without Take, and starts a run that drives until it is ended
        assert drive(alice, '/s01') is None
        poses.wait(lambda p: p['x'] > START + 0.05)
        source = program('''
while True:
    rt.publish("/s01/turtle1/cmd_vel", "geometry_msgs/msg/Twist", {"linear": {"x": 0.5}, "angular": {"z": 0.3}})
    rt.sleep(0.05)
''')
        status, run = api(lab, 'POST', '/api/runs', {'source': source, 'name': 'circles', 'ns': '/s01'},
                          token=TOKENS['operator'])
        assert status == 201, run
        wait_for(lambda: state_of(lab, run['id'], TOKENS['operator'])['state'] == 'running', 30, 0.1)
        poses.wait(lambda p: abs(p['angular_velocity'] - 0.3) < 1e-6, 20)   # the run is driving

        # the end: nobody acts; the gateway stops, frees and resets the station
        end = hers['end']
        back = poses.wait(lambda p: at_start(p) and time.time() > end, 30)
        assert back['linear_velocity'] == 0 and back['angular_velocity'] == 0 and back['theta'] == 0
        wait_for(lambda: len([s for s in poses.pump() if s[0] > end]) >= 20, 10)   # 20 poses after it
        after = [(at, p) for at, p in poses.pump() if at > end]
        moving = [at for at, p in after if not at_start(p)]
        stopped_at = max(moving) if moving else end
        assert stopped_at - end <= 1.0, f'the turtle still moved {stopped_at - end:.2f} s after the end'
        assert all(at_start(p) and p['linear_velocity'] == 0 for at, p in after if at > stopped_at)
        assert wait_for(lambda: state_of(lab, run['id'], TOKENS['operator'])['state'] in ENDED, 15, 0.1)
        assert 'slot on /s01 ended' in state_of(lab, run['id'], TOKENS['operator'])['output']

        # alice is refused now; bob's slot began and he drives without Take
        wait_for(lambda: stations_info(watcher)['owners'].get('/s01', {}).get('name') == 'bob', 10, 0.1)
        refusal = drive(alice, '/s01')
        assert refusal is not None and 'bob' in refusal['msg'], refusal
        assert drive(bob, '/s01') is None
        poses.wait(lambda p: p['x'] > START + 0.05, 10)
        drive(bob, '/s01', 0.0)
        api(lab, 'DELETE', f'/api/bookings/{his["id"]}', token=TOKENS['operator2'])
        wait_for(lambda: '/s01' not in stations_info(watcher)['owners'], 10, 0.1)


def test_bookings_survive_a_restart(start_gateway, tokens_file, tmp_path):
    db = f'sqlite:///{tmp_path / "rosgate.db"}'
    first = start_gateway(*LAB, '--auth', tokens_file, '--db', db)
    t = time.time() + 3600
    status, made = book(first, 'operator', '/s02', t, t + 10)
    assert status == 201
    first.stop()
    again = start_gateway(*LAB, '--auth', tokens_file, '--db', db)
    status, listed = api(again, 'GET', '/api/bookings', token=TOKENS['operator'])
    assert status == 200 and [(b['id'], b['station'], b['start']) for b in listed['bookings']] == \
        [(made['id'], '/s02', t)]
    assert book(again, 'operator2', '/s02', t + 1, t + 9)[0] == 409
    again.stop()


def test_an_observer_of_every_station_leaves_every_station_claimable(launch):
    """Watching is not claiming: with a page subscribed to every station's pose, three people
    still get the three stations."""
    gw = launch('--robot', 'turtlesim', '--fleet', '3', '--exclusive-control')
    with connect(gw) as observer:
        got = {ns: queue.Queue() for ns in ('/s01', '/s02', '/s03')}
        for ns, q in got.items():
            roslibpy.Topic(observer, f'{ns}/turtle1/pose', POSE).subscribe(q.put)
        for q in got.values():
            q.get(timeout=10)
        people = [Client(gw.ws_url) for _ in range(3)]
        try:
            answers = [p.call('/fleet/claim')['values'] for p in people]
            assert all(a['success'] for a in answers), answers
            assert sorted(a['message'] for a in answers) == ['/s01', '/s02', '/s03']
        finally:
            for p in people:
                p.close()


def test_walk_ins_hold_until_the_next_booking_and_queue_when_all_are_taken(lab):
    """Bob walks into /s02 (the page can say until when: the next booking); with both stations
    taken the teacher queues, is told the estimated wait and is seated at /s01 when alice's slot
    there ends; at the start of alice's booking of /s02 bob's walk-in ends."""
    with connect(lab, TOKENS['admin']) as teacher, Client(lab.ws_url, TOKENS['operator2']) as bob, \
            Client(lab.ws_url, TOKENS['admin']) as teacher_page:
        roslibpy.Service(teacher, '/fleet/release_all', 'std_srvs/srv/Empty').call(roslibpy.ServiceRequest({}), timeout=10)
        t0 = time.time()
        _, first = book(lab, 'operator', '/s01', t0 + 2, t0 + 8)
        _, later = book(lab, 'operator', '/s02', t0 + 10, t0 + 14)
        wait_for(lambda: stations_info(teacher)['owners'].get('/s01', {}).get('name') == 'alice', 10, 0.1)
        assert bob.call('/fleet/claim')['values'] == {'success': True, 'message': '/s02'}
        info = stations_info(teacher)
        assert info['next']['/s02']['start'] == later['start']      # bob's walk-in holds until then
        assert 'until' in bob.call('/s01/fleet/claim')['values']['message']   # alice's, booked: until when
        assert api(lab, 'POST', '/api/queue', token=TOKENS['viewer'])[0] == 403
        assert api(lab, 'POST', '/api/queue', token=TOKENS['operator2'])[0] == 409     # bob has /s02
        status, queued = api(lab, 'POST', '/api/queue', token=TOKENS['admin'])
        assert status == 201 and queued['place'] == 1 and queued['line'] == ['teacher'], queued
        assert 0 < queued['wait'] <= first['end'] - time.time() + 1                        # alice's slot end
        wait_for(lambda: stations_info(teacher)['queue'] == ['teacher'], 10, 0.1)
        # alice's slot ends: the teacher is seated there from the queue
        seated = wait_for(lambda: (lambda q: q if q['seated'] else None)(
            api(lab, 'GET', '/api/queue', token=TOKENS['admin'])[1]), 15, 0.1)
        assert seated['seated'] == '/s01' and seated['station'] == '/s01' and seated['place'] is None
        assert teacher_page.call('/fleet/claim')['values'] == {'success': True, 'message': '/s01'}
        # alice's booking of /s02 begins: bob's walk-in is over
        wait_for(lambda: stations_info(teacher)['owners'].get('/s02', {}).get('name') == 'alice', 15, 0.1)
        refusal = drive(bob, '/s02')
        assert refusal is not None and 'alice' in refusal['msg'], refusal
        assert api(lab, 'DELETE', f'/api/bookings/{later["id"]}', token=TOKENS['operator'])[0] == 200
        roslibpy.Service(teacher, '/fleet/release_all', 'std_srvs/srv/Empty').call(roslibpy.ServiceRequest({}), timeout=10)


def test_a_booked_station_the_teacher_released_is_still_nobody_elses(lab):
    with connect(lab, TOKENS['admin']) as teacher, Client(lab.ws_url, TOKENS['operator']) as alice, \
            Client(lab.ws_url, TOKENS['operator2']) as bob:
        t0 = time.time()
        status, hers = book(lab, 'operator', '/s01', t0 + 1, t0 + 15)
        assert status == 201, hers
        wait_for(lambda: stations_info(teacher)['owners'].get('/s01', {}).get('name') == 'alice', 10, 0.1)
        released = roslibpy.Service(teacher, '/s01/fleet/release', 'std_srvs/srv/Trigger').call(
            roslibpy.ServiceRequest({}), timeout=10)
        assert released['success'], released
        answer = bob.call('/s01/fleet/claim')['values']
        assert answer['success'] is False and 'booked by alice' in answer['message'], answer
        refusal = drive(bob, '/s01')
        assert refusal is not None and 'booked by alice' in refusal['msg'], refusal
        assert alice.call('/s01/fleet/claim')['values'] == {'success': True, 'message': '/s01'}
        assert stations_info(teacher)['owners']['/s01']['until'] == hers['end']
        assert api(lab, 'DELETE', f'/api/bookings/{hers["id"]}', token=TOKENS['operator'])[0] == 200
        wait_for(lambda: '/s01' not in stations_info(teacher)['owners'], 10, 0.1)
