"""The database faults a lesson meets, for a fleet of two gateways A and B (tests/support/fleet.py):
PostgreSQL restarted (down while the teacher acts, then back), B's connections killed
(``pg_terminate_backend``), and the database unreachable from B for CUT seconds (B's --db goes
through a tests/support/pgproxy.Relay). What must hold through each (store.fleet, rules.settle):
a Stop and a logout sent through A reach B (at once, or when B can read again: they are rows), a
gateway that cannot confirm the shared state takes no new lease and ends the lease it holds (its
driver stopped and told why), a booked slot ends on every gateway and its station is reset once.

Every wait is for an event (a message, a status, a reply, a log line) with a generous deadline."""

from __future__ import annotations

import json
import threading
import time
from contextlib import contextmanager

from .auth import TOKENS, login
from .fleet import claim, drive, owner_on, stations
from .http import http
from .postgres import kill_ports
from .wait import wait_for
from .wsclient import TWIST, Client, is_zero_twist, twist

FAULTS = ('restart', 'kill', 'cut')
CUT = 10.0         # s the database is unreachable from B


class Faults:
    """The faults, for gateway ``b``: ``pg`` (tests/support/postgres.Postgres), ``relay`` (B's).
    ``ended``: when the last fault ended (time.monotonic()), for the figures the cases print."""

    def __init__(self, pg, relay, b):
        self.pg, self.relay, self.b = pg, relay, b
        self.began = self.ended = 0.0

    @contextmanager
    def during(self, fault: str):
        """The block runs while the fault holds: PostgreSQL down ('restart': started again on the
        way out), B's connections just killed ('kill'), B cut off ('cut': the way out waits for
        the link's return)."""
        self.began = time.monotonic()
        if fault == 'restart':
            self.pg.stop()
            try:
                yield
            finally:
                self.pg.start()
        elif fault == 'kill':   # every connection of B's (they all come through its relay)
            assert kill_ports(self.pg, self.relay.ports()) > 0, 'B has no connection to kill'
            yield
        else:
            back = self.relay.cut(CUT)
            yield
            wait_for(lambda: time.monotonic() > back, CUT + 5, 0.05, what='the link back')
        self.ended = time.monotonic()


class Stream:
    """A student's teleop: a moving command every 0.1 s (the pace of a held key) on one station,
    with an id each; the gateway's answers land in the client's ``seen``/``expect`` as usual."""

    def __init__(self, client: Client, ns: str, x: float = 1.0):
        self.client, self.topic, self.x = client, f'{ns}/turtle1/cmd_vel', x
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.done.is_set():
            self.client.publish(self.topic, twist(self.x), TWIST)
            self.done.wait(0.1)     # the stream's pace, not a wait for an event

    def stop(self) -> None:
        self.done.set()
        self.thread.join(5)


def refusal_with(client: Client, words: str, timeout: float = 30) -> dict:
    """The next error status (a refused op) whose text has ``words``."""
    return client.expect(lambda m: m.get('op') == 'status' and m.get('level') == 'error'
                         and words in m.get('msg', ''), timeout)


def told(client: Client, words: str, timeout: float = 30) -> dict:
    """The next status of any level whose text has ``words``."""
    return client.expect(lambda m: m.get('op') == 'status' and words in m.get('msg', ''), timeout)


def health(gw) -> dict:
    return http(gw, '/health').json()


def drive_again(client: Client, ns: str, x: float) -> None:
    """A command that is not refused at once (a stop or a bar this gateway has not let go of yet
    is): sent again until it is. Whether it moves the robot, the robot says."""
    last = []

    def sent() -> bool:
        last[:] = [drive(client, ns, x)]
        return last[0] is None
    try:
        wait_for(sent, 30, 0.2, what=f'a command on {ns} not refused at once')
    except AssertionError as e:
        raise AssertionError(f'{e}; the last refusal: {last}') from None


def stop_through_a(a, b, faults: Faults, fault: str, follow) -> None:
    """bob drives /s02 through B; the fault; the teacher's Stop through A while it holds. B applies
    the Stop (at once, or when it can read again): the robot gets its zero and bob's commands are
    refused naming the Stop; while B cannot reach the database ('cut') it ends bob's lease by itself
    (the robot zeroed, bob told why) and takes no new one. Nothing of bob's moves the robot after
    that until the teacher's Release and his new claim: the next motion is the one he sends then."""
    with Client(a.ws_url, TOKENS['admin']) as teacher, Client(b.ws_url, TOKENS['operator2']) as bob, \
            Client(b.ws_url, TOKENS['viewer']) as watcher:
        assert claim(bob, '/s02/fleet/claim')['success'] is True
        heard = follow(watcher, '/s02')
        bob.send({'op': 'set_level', 'level': 'info'})
        stream = Stream(bob, '/s02')
        try:
            heard(lambda m: m['linear']['x'] == 1.0, 15)
            with faults.during(fault):
                teacher.publish('/rosgate/control', {'data': 'stop /s02'}, 'std_msgs/msg/String')
                sent = time.monotonic()
                if fault == 'cut':    # B alone: its lease ends with its expiry, and no new one
                    told(bob, 'has not reached its database')
                    ended = time.monotonic() - faults.began
                    heard(is_zero_twist, 15)
                    refusal_with(bob, 'cannot be confirmed with the other gateways')
            stop = refusal_with(bob, 'stopped /s02')           # the Stop, heard or read by B
            known = time.monotonic()
            assert 'teacher' in stop['msg'], stop
            if fault != 'cut':
                heard(is_zero_twist, 15)
            print(f'\n{fault}: the Stop sent through A {sent - faults.began:.2f} s into the fault refused bob on B '
                  f'{known - sent:.2f} s after it was sent, {known - faults.ended:+.2f} s from the fault\'s end'
                  + (f'; B ended his lease by itself {ended:.2f} s into the cut' if fault == 'cut' else ''))
        finally:
            stream.stop()
        stations(teacher)     # B's claim is bob's again on A (a cut let its row lapse for a while)
        wait_for(lambda: owner_on(teacher, '/s02') == 'bob', 30, 0.0, what="bob's claim on A")
        assert teacher.call('/s02/fleet/release')['values']['success'] is True
        told(bob, 'teacher released /s02')                      # B has it: bob claims again
        assert claim(bob, '/s02/fleet/claim')['success'] is True
        drive_again(bob, '/s02', 0.5)
        moved = heard(lambda m: not is_zero_twist(m), 15)
        assert moved['linear']['x'] == 0.5, moved          # no 1.0 of before reached the robot
        drive(bob, '/s02', 0.0)
        bob.call('/s02/fleet/release')


def logout_through_a(a, b, faults: Faults, fault: str) -> None:
    """alice signs in on A; her cookie works on B, where she has a websocket open. The fault; her
    logout through A while it holds. A answers once the sign-out is committed and B refuses it (or
    cannot confirm any sign-in): a request on B right after the answer is refused; once B can read
    again it refuses it as ended (401) and her websocket there is closed."""
    cookie = login(a, TOKENS['operator'])
    headers = {'Cookie': cookie}
    wait_for(lambda: http(b, '/whoami', headers=headers).status == 200, 15, 0.05, what='the sign-in known on B')
    with Client(b.ws_url, additional_headers=headers) as socket_on_b:
        assert socket_on_b.call('/rosapi/get_time')['result'] is True
        answer = {}

        def logout() -> None:   # and at once, the same cookie on B
            answer['reply'] = http(a, '/logout', headers=headers, timeout=60)
            answer['at'] = time.monotonic()
            answer['on b'] = http(b, '/whoami', headers=headers).status
        thread = threading.Thread(target=logout)
        with faults.during(fault):
            sent = time.monotonic()
            thread.start()
        thread.join(60)
        answered, right_after = answer['at'], answer['on b']
        assert answer['reply'].status == 303, answer['reply']
        assert right_after in (401, 503), right_after        # refused: ended, or not confirmable now
        wait_for(lambda: http(b, '/whoami', headers=headers).status == 401, 30, 0.05, what='401 on B')
        assert http(a, '/whoami', headers=headers).status == 401
        assert socket_on_b.closed_code(30) == 1008
        print(f'\n{fault}: the logout through A answered after {answered - sent:.2f} s; a request on B right '
              f'after got {right_after}; her websocket on B closed {time.monotonic() - faults.ended:+.2f} s from the '
              f'fault\'s end')


def first_commands_at_once(a, b, robot, rounds: int = 50) -> dict:
    """alice (through A) and bob (through B) send their first command on the free /s01 at the same
    instant, ``rounds`` times: each time exactly one gets the lease (told so), the other is refused
    naming her or him, and the robot receives the winner's command and nothing of the loser's.
    ``robot(ns)``: the commands the robot of ``ns`` has received, in order (a list that grows)."""
    wins = {'alice': 0, 'bob': 0}
    with Client(a.ws_url, TOKENS['operator']) as alice, Client(b.ws_url, TOKENS['operator2']) as bob, \
            Client(a.ws_url, TOKENS['viewer']) as va, Client(b.ws_url, TOKENS['viewer']) as vb:
        people = {'alice': alice, 'bob': bob}
        topic = '/s01/turtle1/cmd_vel'
        for c in people.values():
            c.send({'op': 'set_level', 'level': 'info'})
            assert c.refusal({'op': 'advertise', 'topic': topic, 'type': TWIST}) is None
        for v in (va, vb):
            v.subscribe('/rosgate/driver', 'std_msgs/msg/String')
        gws = (health(a)['fleet']['gateway'], health(b)['fleet']['gateway'])
        for n in range(rounds):
            speeds = {'alice': 0.1 + n / 100, 'bob': -(0.1 + n / 100)}
            ids = {name: f'publish:first:{n}:{name}' for name in people}
            gate = threading.Barrier(2)
            verdicts: dict = {}

            def first(name: str) -> None:
                c = people[name]
                gate.wait(10)
                c.send({'op': 'publish', 'topic': topic, 'id': ids[name], 'msg': twist(speeds[name])})
                m = c.expect(lambda m: m.get('op') == 'status' and (
                    m.get('id') == ids[name] and m.get('level') == 'error'
                    or 'you hold the driver lease' in m.get('msg', '')), 20)
                verdicts[name] = m
            threads = [threading.Thread(target=first, args=(name,)) for name in people]
            for t in threads:
                t.start()
            for t in threads:
                t.join(30)
            won = [name for name, m in verdicts.items() if m.get('level') != 'error']
            assert len(won) == 1 and len(verdicts) == 2, (n, verdicts)
            winner = won[0]
            loser = 'bob' if winner == 'alice' else 'alice'
            assert winner in verdicts[loser]['msg'], (n, verdicts)
            wins[winner] += 1
            wait_for(lambda: any(m['linear']['x'] == speeds[winner] for m in robot('/s01')), 20, 0.0,
                     what=f"round {n}: {winner}'s command at the robot")
            assert not any(m['linear']['x'] == speeds[loser] for m in robot('/s01')), (n, robot('/s01')[-5:])
            for v in (va, vb):
                v.seen.clear()
            w = people[winner]
            w.publish(topic, twist(0.0))
            w.publish('/rosgate/control', {'data': 'release /s01'}, 'std_msgs/msg/String')
            for v, gw in ((va, gws[0]), (vb, gws[1])):   # each gateway's own word (one graph: v hears both)
                v.next_message('/rosgate/driver', lambda m, gw=gw: _free(m, gw, '/s01'), 20)
    return wins


def _free(msg: dict, gateway: str, ns: str) -> bool:
    info = json.loads(msg['data'])
    return info.get('fleet', {}).get('gateway') == gateway and info['drivers'].get(ns) is None


def stop_known_to_a_later_gateway(a, start_c, follow) -> None:
    """The teacher stops /s02 through A; a gateway C started after that refuses a student's command
    on /s02 naming the Stop, and nothing of it reaches the robot."""
    with Client(a.ws_url, TOKENS['admin']) as teacher:
        teacher.publish('/rosgate/control', {'data': 'stop /s02'}, 'std_msgs/msg/String')
        teacher.subscribe('/rosgate/driver', 'std_msgs/msg/String')
        teacher.next_message('/rosgate/driver', lambda m: '/s02' in json.loads(m['data'])['halted'], 15)
        c = start_c()
        with Client(c.ws_url, TOKENS['operator2']) as bob, Client(c.ws_url, TOKENS['viewer']) as watcher:
            heard = follow(watcher, '/s02')
            refusal = drive(bob, '/s02')
            assert refusal is not None and 'teacher' in refusal['msg'] and 'stopped /s02' in refusal['msg'], refusal
            assert drive(bob, '/s02', 0.5) is not None    # again: the Stop holds on C
            teacher.publish('/rosgate/control', {'data': 'release /s02'}, 'std_msgs/msg/String')
            stream = Stream(bob, '/s02', 0.25)   # (a new publisher's first messages may go before the robot hears it)
            try:
                moved = heard(lambda m: not is_zero_twist(m), 30)
            finally:
                stream.stop()
            assert moved['linear']['x'] == 0.25, moved          # neither refused command reached the robot
            drive(bob, '/s02', 0.0)
            bob.publish('/rosgate/control', {'data': 'release /s02'}, 'std_msgs/msg/String')


def slot_end_while_another_gateway_still_seats(a, b, pg, follow) -> None:
    """Each gateway ends a slot on its own clock, and the station's one claim row names the gateway
    that seated the booker last: here A, which cannot drop it at the end (the test holds its row
    locked). alice drives through B: when her slot ends B refuses her and zeroes the robot, though
    A's claim still says she has the station (a claim held elsewhere is not hers past her slot)."""
    import sqlalchemy as sa
    with Client(a.ws_url, TOKENS['operator']) as alice_a, Client(b.ws_url, TOKENS['operator']) as alice, \
            Client(b.ws_url, TOKENS['viewer']) as watcher:
        begin = time.time() + 2
        status, slot = http_api(a, {'station': '/s01', 'start': begin, 'end': begin + 4, 'for': 'alice'})
        assert status == 201, slot
        stations(watcher)
        wait_for(lambda: owner_on(watcher, '/s01') == 'alice', 30, 0.0, what='alice seated at /s01 by B')
        row = lambda: pg.sql("SELECT gateway FROM fleet_holds WHERE kind = 'claim' AND name = '/s01'")  # noqa: E731
        a_id = health(a)['fleet']['gateway']
        wait_for(lambda: alice_a.call('/s01/fleet/claim')['values']['success'] and row() == [(a_id,)], 30, 0.2,
                 what="/s01's claim row naming A (her claim through A written after B's seat)")
        heard = follow(watcher, '/s01')
        stream = Stream(alice, '/s01')
        engine = sa.create_engine(pg.url)
        try:
            heard(lambda m: m['linear']['x'] == 1.0, 15)
            with engine.connect() as c:
                tx = c.begin()
                c.execute(sa.text("SELECT 1 FROM fleet_holds WHERE kind = 'claim' AND name = '/s01' FOR UPDATE"))
                refusal_with(alice, 'slot on /s01 has ended')   # B's clock; A cannot drop its claim
                heard(is_zero_twist, 15)
                tx.rollback()
            # A's writes waited on the lock: it confirms its claims again before the next test claims
            wait_for(lambda: not health(a)['fleet']['unreachable'], 30, what='A reaching its database again')
        finally:
            stream.stop()
            engine.dispose()


def http_api(gw, body: dict):
    from .http import api
    return api(gw, 'POST', '/api/bookings', body, token=TOKENS['admin'])


def release_through_the_other_gateway(a, b) -> None:
    """alice claims /s01 through A and gives it back through B: A no longer counts it hers (the row
    is ended, whichever gateway holds it), and bob claims it through A."""
    with Client(a.ws_url, TOKENS['operator']) as alice_a, Client(b.ws_url, TOKENS['operator']) as alice_b, \
            Client(a.ws_url, TOKENS['operator2']) as bob, Client(b.ws_url, TOKENS['viewer']) as watcher:
        assert claim(alice_a, '/s01/fleet/claim')['success'] is True
        stations(watcher)
        wait_for(lambda: owner_on(watcher, '/s01') == 'alice', 30, 0.0, what="alice's claim known on B")
        assert alice_b.call('/s01/fleet/release')['values']['success'] is True
        stations(bob)
        wait_for(lambda: owner_on(bob, '/s01') is None, 30, 0.0, what='/s01 free on A')
        assert claim(bob, '/s01/fleet/claim') == {'success': True, 'message': '/s01'}
        bob.call('/s01/fleet/release')
