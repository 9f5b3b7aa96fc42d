"""A fleet of gateways on one PostgreSQL (store.fleet, rules.fleet) in tests: two gateway processes
with the same --db, --auth and data folder (the cookie secret), and the cases every fleet must pass
whichever backend its gateways run (tests/security/test_fleet.py: sim gateways, each with its
robots in its own process; tests/backends/test_fleet_graph.py: rclpy gateways on one ROS 2 graph
with the robots on it).

The cases differ only in where they read the robot's velocity commands: ``follow(watcher, ns)``
gives ``heard(predicate, timeout)``, the next command the robot of station ``ns`` receives from
then on that matches (in the order received), or raises after ``timeout`` seconds. On the sim the
watcher (a client of gateway B) subscribes to what B publishes; on the graph it is the robot's own
subscription, which hears every gateway."""

from __future__ import annotations

import json
import signal
import threading
import time

import sqlalchemy as sa

from .auth import TOKENS, login
from .http import api, http
from .wait import wait_for
from .wsclient import TWIST, Client, is_zero_twist, twist

# --cmd-timeout 5: the dead-man's zero (1 s by default) is not taken for the Stop's
FLAGS = ('--exclusive-control', '--booking', '--slot-minutes', '0.25', '--cmd-timeout', '5')
HOLD = 3.0           # s: a dead gateway's claims and leases lapse within this (store.fleet)


def start_pair(start, tokens_file: str, postgres: str, data: str, *flags: str, b_db: str | None = None) -> list:
    """Gateways A and B of one fleet (B started second), ``start(*flags, env=...)`` each; ``data``
    is their one data folder (one cookie secret, as a fleet shares it); ``b_db``: B's way to the
    database, when not ``postgres`` (a tests/support/pgproxy.Relay's, to cut B off)."""
    return [start(*FLAGS, *flags, '--auth', tokens_file, '--db', url, env={'XDG_DATA_HOME': data})
            for url in (postgres, b_db or postgres)]


def claim(c: Client, service: str = '/fleet/claim') -> dict:
    """A claim's answer, asked again while the gateway says to try again in a moment (it has not
    confirmed its database within the hold: on a starved machine its beat comes late, and it
    rightly takes no lease it cannot confirm); any other answer at once."""
    def answer():
        values = c.call(service)['values']
        return None if 'try again in a moment' in values.get('message', '') else values
    return wait_for(answer, 30, 0.2, what=f'an answer to {service} that is not "try again"')


def stations(c: Client) -> None:
    """Follow the gateway's /rosgate/stations (latched: its state now, then each change)."""
    c.subscribe('/rosgate/stations', 'std_msgs/msg/String')


def announced(c: Client) -> dict:
    """The next announcement on /rosgate/stations of the gateway of ``c`` (each change is
    announced: wait_for(... announced ...) reads them in order until one matches)."""
    return json.loads(c.next_message('/rosgate/stations', timeout=10)['data'])


def owner_on(c: Client, ns: str) -> str | None:
    """Who the next announcement names as the station's owner."""
    return announced(c)['owners'].get(ns, {}).get('name')


def drive(c: Client, ns: str, x: float = 1.0) -> dict | None:
    return c.refusal({'op': 'publish', 'topic': f'{ns}/turtle1/cmd_vel', 'type': TWIST, 'msg': twist(x)})


def client_follow(watcher: Client, ns: str):
    """``follow`` on the sim: what gateway B publishes on the station's command topic, read by its
    client ``watcher`` in order (each message read once, matching or not)."""
    topic = f'{ns}/turtle1/cmd_vel'
    watcher.subscribe(topic, TWIST)

    def heard(predicate, timeout: float) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            msg = watcher.next_message(topic, timeout=max(0.0, deadline - time.monotonic()))
            if predicate(msg):
                return msg
    return heard


def one_station_one_person(a, b) -> None:
    """Two students on two gateways claim one station: one is refused, naming the holder."""
    with Client(a.ws_url, TOKENS['operator']) as alice, Client(b.ws_url, TOKENS['operator2']) as bob:
        assert claim(alice, '/s01/fleet/claim') == {'success': True, 'message': '/s01'}
        stations(bob)
        wait_for(lambda: owner_on(bob, '/s01') == 'alice', 10)
        reply = bob.call('/s01/fleet/claim')
        answer = reply['values']
        assert reply['result'] and answer['success'] is False and "alice" in answer['message'], reply
        refusal = drive(bob, '/s01')
        assert refusal is not None and 'alice' in refusal['msg'], refusal
        # the lease too: alice drives through A, bob may not take it on B
        assert drive(alice, '/s01') is None
        bob.subscribe('/rosgate/driver', 'std_msgs/msg/String')   # B's class page shows who drives through A
        driver = lambda m: (json.loads(m['data'])['drivers'].get('/s01') or {})   # noqa: E731
        shown = driver(bob.next_message('/rosgate/driver', lambda m: driver(m).get('elsewhere'), timeout=5))
        assert shown['name'].startswith('alice') and shown['owner'] is True, shown
        assert claim(bob, '/fleet/claim') == {'success': True, 'message': '/s02'}
        refusal = drive(bob, '/s01')
        assert refusal is not None and 'alice' in refusal['msg'], refusal
        for c, ns in ((alice, '/s01'), (bob, '/s02')):
            drive(c, ns, 0.0)
            c.call(f'{ns}/fleet/release')


def claims_at_once(a, b, rounds: int = 3) -> None:
    """Two students ask two gateways for one station at the same moment (neither gateway has heard
    the other's claim yet): one yes, one no naming the holder, and both gateways show the one owner."""
    with Client(a.ws_url, TOKENS['operator']) as alice, Client(b.ws_url, TOKENS['operator2']) as bob:
        stations(alice)
        stations(bob)
        for _ in range(rounds):
            gate = threading.Barrier(2)
            answers: dict = {}

            def ask(name: str, c: Client) -> None:
                gate.wait(5)
                answers[name] = c.call('/s01/fleet/claim')['values']
            threads = [threading.Thread(target=ask, args=pair) for pair in (('alice', alice), ('bob', bob))]
            for t in threads:
                t.start()
            for t in threads:
                t.join(15)
            won = [name for name, answer in answers.items() if answer['success']]
            assert len(won) == 1, answers
            lost = 'bob' if won == ['alice'] else 'alice'
            assert won[0] in answers[lost]['message'], answers
            for c in (alice, bob):
                wait_for(lambda c=c: owner_on(c, '/s01') == won[0], 10, what=f'{won[0]} the owner on both gateways')
            winner = alice if won == ['alice'] else bob
            assert winner.call('/s01/fleet/release')['values']['success'] is True
            for c in (alice, bob):
                wait_for(lambda c=c: owner_on(c, '/s01') is None, 10, what='/s01 free on both gateways')


def one_line(a, b) -> None:
    """The walk-in line is the fleet's: the teacher queues through B while both stations are held
    through A; A lists her in its line, refuses the free station to anyone else, and when alice
    gives hers back through A, B seats the teacher there (her turn) and the line is empty on A."""
    def line_on(gw) -> list:
        status, body = api(gw, 'GET', '/api/queue', token=TOKENS['operator2'])
        assert status == 200, body
        return body['line']
    with Client(a.ws_url, TOKENS['operator']) as alice, Client(a.ws_url, TOKENS['operator2']) as bob, \
            Client(b.ws_url, TOKENS['admin']) as teacher:
        stations(teacher)
        assert claim(alice, '/s01/fleet/claim')['success'] is True
        assert claim(bob, '/s02/fleet/claim')['success'] is True
        wait_for(lambda: announced(teacher)['owners'].keys() >= {'/s01', '/s02'}, 10, what='both held, on B')
        status, body = api(b, 'POST', '/api/queue', {}, token=TOKENS['admin'])
        assert status == 201 and body['place'] == 1, body
        wait_for(lambda: line_on(a) == ['teacher'], 10, what="the teacher in A's line")
        assert alice.call('/s01/fleet/release')['values']['success'] is True
        wait_for(lambda: owner_on(teacher, '/s01') == 'teacher', 15, what='the teacher seated at /s01 by B')
        wait_for(lambda: line_on(a) == [], 10, what="A's line empty")
        for c, ns in ((teacher, '/s01'), (bob, '/s02')):
            c.call(f'{ns}/fleet/release')


def stop_on_a_halts_b(a, b, follow) -> None:
    """The teacher's Stop on A zeroes the station a student drives through B (how long it took is
    printed: the bound is the benchmark's), and nothing moves it after: her commands are refused until the teacher's Release and her new
    claim, and the next motion the robot receives is the one she sends then (no refused command
    went out in between: one gateway's commands on a topic arrive in order)."""
    with Client(a.ws_url, TOKENS['admin']) as teacher, Client(b.ws_url, TOKENS['operator2']) as bob, \
            Client(b.ws_url, TOKENS['viewer']) as watcher:
        assert claim(bob, '/s02/fleet/claim')['success'] is True
        heard = follow(watcher, '/s02')
        stations(watcher)
        assert drive(bob, '/s02') is None
        heard(lambda m: m['linear']['x'] == 1.0, 5)
        teacher.publish('/rosgate/control', {'data': 'stop /s02'}, 'std_msgs/msg/String')
        stopped = time.monotonic()
        heard(is_zero_twist, 15)
        print(f'\nthe Stop through A reached the robot driven through B in {(time.monotonic() - stopped) * 1000:.0f} ms')
        for _ in range(3):    # she keeps driving at 10 Hz through B
            refusal = drive(bob, '/s02')
            assert refusal is not None and 'teacher' in refusal['msg'] and 'stopped /s02' in refusal['msg'], refusal
            time.sleep(0.1)   # the stream's pace, not a wait for an event
        # the teacher's Release on A frees it on B as well (her class page on A shows it bob's)
        stations(teacher)
        wait_for(lambda: owner_on(teacher, '/s02') == 'bob', 5)
        answer = teacher.call('/s02/fleet/release')['values']
        assert answer['success'] is True, answer
        wait_for(lambda: owner_on(watcher, '/s02') is None, 10)
        refusal = drive(bob, '/s02')
        assert refusal is not None and 'teacher released /s02' in refusal['msg'], refusal
        assert claim(bob, '/s02/fleet/claim')['success'] is True   # she claims again: hers
        assert drive(bob, '/s02', 0.5) is None
        moved = heard(lambda m: not is_zero_twist(m), 5)
        assert moved['linear']['x'] == 0.5, moved    # no refused 1.0 reached the robot
        drive(bob, '/s02', 0.0)
        bob.call('/s02/fleet/release')


def logout_everywhere(a, b) -> None:
    """A sign-in on A holds on B (a proxy that is not sticky); a logout on A ends it on B at once."""
    cookie = login(a, TOKENS['operator'])
    whoami = lambda gw: http(gw, '/whoami', headers={'Cookie': cookie})   # noqa: E731
    on_b = wait_for(lambda: (lambda r: r if r.status == 200 else None)(whoami(b)), 5, 0.05)
    assert on_b.json()['name'] == 'alice'
    assert http(a, '/logout', headers={'Cookie': cookie}).status in (303, 200)
    ended = time.monotonic()
    wait_for(lambda: whoami(b).status == 401, 2, 0.02)
    assert time.monotonic() - ended < 1.0
    assert whoami(a).status == 401


def history_once(pair, postgres: str) -> None:
    """Only one gateway of the fleet (its timekeeper) writes the history; the rows are its rows."""
    a, b = pair
    stats = lambda gw: api(gw, 'GET', '/api/history/stats', token=TOKENS['admin'])[1]   # noqa: E731
    writer = wait_for(lambda: next((gw for gw in pair if stats(gw)['rows_written'] > 0), None), 30, 0.2)
    other = b if writer is a else a
    assert stats(other)['rows_written'] == 0
    engine = sa.create_engine(postgres)
    with engine.connect() as c:
        rows = c.execute(sa.text('SELECT count(*) FROM history_points')).scalar()
    engine.dispose()
    assert rows >= 1 and rows <= stats(writer)['rows_written']


def slot_ends_with_a_killed(a, b, follow) -> None:
    """A slot booked through A seats its booker on B; A dies (SIGKILL) while bob drives /s02 through
    it: its claims and leases lapse within HOLD, B zeroes /s02's commands, and B's timekeeper ends
    the slot on time, refusing her commands and zeroing the robot."""
    with Client(b.ws_url, TOKENS['operator']) as alice, Client(b.ws_url, TOKENS['viewer']) as watcher, \
            Client(a.ws_url, TOKENS['operator2']) as bob, Client(b.ws_url, TOKENS['admin']) as teacher:
        got = claim(bob, '/s02/fleet/claim')
        assert got['success'] is True, got    # bob drives /s02 through A
        assert drive(bob, '/s02') is None
        begin = time.time() + 2
        status, slot = api(a, 'POST', '/api/bookings', {'station': '/s01', 'start': begin, 'end': begin + 10},
                           token=TOKENS['operator'])
        assert status == 201, slot
        stations(watcher)
        wait_for(lambda: owner_on(watcher, '/s01') == 'alice', 10)   # B seats her: it heard the booking
        heard = follow(watcher, '/s01')
        assert drive(alice, '/s01') is None
        heard(lambda m: m['linear']['x'] == 1.0, 5)
        answer = wait_for(lambda: (lambda v: v if 'bob' in v['message'] else None)(
            teacher.call('/s02/fleet/claim')['values']), 5)
        assert answer['success'] is False, answer
        heard_s02 = follow(watcher, '/s02')
        assert drive(bob, '/s02') is None
        a.stop(signal.SIGKILL)
        killed = time.monotonic()
        # A's dead-man died with it: when its lease on /s02 lapses, B zeroes what bob left moving
        heard_s02(is_zero_twist, HOLD + 15)
        print(f'\nthe killed gateway\'s robot got its zero from the other in {time.monotonic() - killed:.2f} s')
        # A's claims and leases lapse within HOLD of its death: the teacher on B claims /s02
        wait_for(lambda: teacher.call('/s02/fleet/claim')['values']['success'], 20, 0.1)
        refusal = None
        while refusal is None and time.time() < slot['end'] + 30:   # she keeps driving at 10 Hz through B
            refusal = drive(alice, '/s01')
            time.sleep(0.1)   # the stream's pace, not a wait for an event
        late = time.time() - slot['end']
        assert refusal is not None and 'slot on /s01 has ended' in refusal['msg'], refusal
        assert late > -0.1, late          # not before its end (how late is printed: the bound is the benchmark's)
        print(f'the slot ended {late * 1000:+.0f} ms from its booked end')
        heard(is_zero_twist, 15)
