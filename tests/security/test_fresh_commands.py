"""A command is fresh or it is dropped: stamped commands (``"t"`` on publish, docs/protocol.md)
made before a stop, or that waited too long on the way, never move the robot."""

from __future__ import annotations

import json
import time

import pytest

from gateway.rules.freshness import DRIFT, ClientClock
from tests.support.rawsocket import ServerFrames, client_frame, raw_websocket
from tests.support.wsclient import TWIST, Client, is_zero_twist, twist

TOPIC = '/fresh/cmd_vel'


def ms() -> float:
    return time.monotonic() * 1000.0


@pytest.fixture(scope='module')
def quick(launch):
    return launch('--cmd-timeout', '0.3')


@pytest.fixture(scope='module')
def strict(launch):
    return launch('--cmd-timeout', '0.3', '--require-cmd-stamp')


def ping(client: Client) -> None:
    """A stamped ping (the client's clock, as the pages send it), then a call as a barrier: every
    op sent before has been handled."""
    client.send({'op': 'ping', 'id': client.next_id('ping'), 't': ms()})
    client.call('/rosapi/get_time')


def test_ping_is_answered_with_its_id_and_stamp(quick):
    with Client(quick.ws_url) as c:
        c.send({'op': 'ping', 'id': 'p1', 't': 12.5})
        assert c.expect(lambda m: m.get('id') == 'p1') == {'op': 'pong', 'id': 'p1', 't': 12.5}
        c.send({'op': 'ping'})
        assert c.expect(lambda m: m.get('op') == 'pong') == {'op': 'pong'}


def command(topic: str, x: float, t: float | None) -> dict:
    op = {'op': 'publish', 'topic': topic, 'msg': twist(x)}
    if t is not None:
        op['t'] = t
    return op


def received(watcher: Client, topic: str) -> list[dict]:
    """Everything the watcher got on topic up to now (a service call as a barrier)."""
    watcher.call('/rosapi/get_time')
    got = [m['msg'] for m in watcher.seen if m.get('op') == 'publish' and m.get('topic') == topic]
    watcher.seen = [m for m in watcher.seen if not (m.get('op') == 'publish' and m.get('topic') == topic)]
    return got


def drive_then_stall(gw, topic: str, stamped: bool) -> tuple[list[dict], list[dict]]:
    """Drive at 20 Hz, then go on making commands that a stalled link holds back until the
    dead-man has stopped the robot, then send them all at once (the link's return). Returns what
    the watcher saw from the stop on, and after one fresh command."""
    with Client(gw.ws_url) as watcher, Client(gw.ws_url) as driver:
        watcher.subscribe(topic, TWIST)
        driver.send({'op': 'advertise', 'topic': topic, 'type': TWIST})
        ping(driver)
        for _ in range(5):
            driver.send(command(topic, 0.5, ms() if stamped else None))
            if stamped:
                driver.send({'op': 'ping', 't': ms()})
            time.sleep(0.05)
        watcher.expect(lambda m: m.get('topic') == topic and not is_zero_twist(m['msg']))
        held = []
        stall = time.monotonic()
        while time.monotonic() - stall < 0.8:   # made during the stall, not delivered
            held.append(command(topic, 0.5, ms() if stamped else None))
            if stamped:   # a page pings all along
                held.append({'op': 'ping', 't': ms()})
            time.sleep(0.05)
        watcher.expect(lambda m: m.get('topic') == topic and is_zero_twist(m['msg']), timeout=3)  # dead-man
        watcher.seen = []   # what came before the stop
        driver.send_together(*held)
        ping(driver)   # handled after the backlog
        after_stop = received(watcher, topic)
        driver.send(command(topic, 0.3, ms() if stamped else None))
        ping(driver)
        fresh = received(watcher, topic)
    return after_stop, fresh


def test_stamped_backlog_after_a_dead_man_stop_does_not_move(quick):
    after_stop, fresh = drive_then_stall(quick, TOPIC, stamped=True)
    assert [m for m in after_stop if not is_zero_twist(m)] == []
    assert [m['linear']['x'] for m in fresh] == [0.3]   # motion resumes with a command made after the stop


PING, PONG, TEXT = 0x9, 0xA, 0x1


def test_a_plain_clients_backlog_waits_for_its_pong(quick):
    """A client that stamps nothing (roslibpy, roslibjs's Topic.publish): after the dead-man's
    stop the gateway pings it, and drops its moving commands until the pong; TCP's order puts the
    backlog of a stalled link before the pong. An older pong does not count; after the right one,
    a command moves the robot again."""
    topic = '/plain/cmd_vel'
    with Client(quick.ws_url) as watcher:
        watcher.subscribe(topic, TWIST)
        sock, rest = raw_websocket(quick.host, quick.port)
        frames = ServerFrames(sock, rest)

        def send(op: dict, opcode: int = TEXT) -> None:
            sock.sendall(client_frame(opcode, json.dumps(op).encode()))

        def barrier(id: str) -> None:     # every op sent before has been handled
            send({'op': 'call_service', 'service': '/rosapi/get_time', 'id': id})
            frames.until(TEXT, lambda p: json.loads(p).get('id') == id)

        try:
            send({'op': 'advertise', 'topic': topic, 'type': TWIST})
            for _ in range(4):
                send(command(topic, 0.5, None))
            watcher.expect(lambda m: m.get('topic') == topic and not is_zero_twist(m['msg']))
            # silence: the dead-man zeroes the stream, and pings the client (which reads nothing yet)
            watcher.expect(lambda m: m.get('topic') == topic and is_zero_twist(m['msg']), timeout=3)
            token = frames.until(PING, lambda p: p.startswith(b'rosgate-stop-'))
            watcher.seen = []
            for _ in range(5):       # the backlog: sent before the client read the ping
                send(command(topic, 0.5, None))
            sock.sendall(client_frame(PONG, b''))      # a keep-alive's pong: not the one
            barrier('b1')
            assert [m for m in received(watcher, topic) if not is_zero_twist(m)] == []
            sock.sendall(client_frame(PONG, token))    # it read the ping: what it sends now is fresh
            send(command(topic, 0.3, None))
            barrier('b2')
            assert [m['linear']['x'] for m in received(watcher, topic)] == [0.3]
        finally:
            sock.close()


def test_a_command_that_waited_too_long_is_dropped_with_a_warning(quick):
    topic = '/aged/cmd_vel'
    with Client(quick.ws_url) as watcher, Client(quick.ws_url) as driver:
        watcher.subscribe(topic, TWIST)
        driver.send({'op': 'advertise', 'topic': topic, 'type': TWIST})
        driver.send({'op': 'set_level', 'level': 'warning'})
        for _ in range(3):
            ping(driver)
        driver.send(command(topic, 0.7, ms() - 1000.0))   # made a second ago: stale
        warning = driver.expect(lambda m: m.get('op') == 'status' and m.get('level') == 'warning')
        assert 'dropped' in warning['msg'] and 'cmd-max-age' in warning['msg']
        driver.send(command(topic, 0.0, ms() - 1000.0))   # a zero passes however old
        driver.send(command(topic, 0.2, ms()))
        ping(driver)
        got = received(watcher, topic)
    assert [m['linear']['x'] for m in got] == [0.0, 0.2]


def test_require_cmd_stamp_refuses_unstamped_moving_commands(strict):
    topic = '/strict/cmd_vel'
    with Client(strict.ws_url) as driver:
        driver.send({'op': 'advertise', 'topic': topic, 'type': TWIST})
        error = driver.refusal(command(topic, 0.5, None))
        assert error is not None and 'stamped' in error['msg'] and '--require-cmd-stamp' in error['msg']
        assert driver.refusal(command(topic, 0.0, None)) is None      # a stop is always welcome
        assert driver.refusal(command(topic, 0.5, ms())) is None


def test_bad_stamp_is_a_clear_error(quick):
    with Client(quick.ws_url) as driver:
        error = driver.refusal({'op': 'publish', 'topic': '/x/cmd_vel', 'msg': twist(), 't': 'soon'})
        assert error is not None and "'t'" in error['msg'] and 'number' in error['msg']
        error = driver.refusal({'op': 'ping', 't': -5})
        assert error is not None and "'t'" in error['msg']


def test_client_clock_follows_the_fastest_trip_and_slow_drift():
    clock = ClientClock()
    assert clock.sample(1000.0, 50.0) == 50.0           # the first op sets the base: age 0
    assert clock.sample(1100.0, 50.2) == pytest.approx(50.1, abs=1e-3)   # 100 ms late against the fastest trip
    assert clock.sample(1300.0, 50.3) == pytest.approx(50.3)             # a faster trip lowers the base
    # a clock running slow: the base rises by at most DRIFT per second, so a drift of 0.5 ms/s
    # is followed while a 2 s stall still shows as 2 s
    issued = clock.sample(1300.0 + 100_000 * (1 - 0.0005), 150.3)
    assert 150.3 - issued == pytest.approx(0.0, abs=1e-6)
    issued = clock.sample(1300.0 + 100_000 * (1 - 0.0005) + 1000.0, 153.3)
    assert 153.3 - issued == pytest.approx(2.0 - DRIFT * 3.0, abs=1e-6)


def test_commands_made_before_the_teachers_stop_never_move_after_take(launch):
    """--exclusive-control: the teacher's Stop holds until Take; stamped commands made before the
    Stop and delivered after the Take (a stalled link's backlog) are dropped, later ones drive."""
    gw = launch('--robot', 'turtlesim', '--fleet', '1', '--exclusive-control', '--cmd-timeout', '0')
    topic = '/s01/turtle1/cmd_vel'
    with Client(gw.ws_url) as watcher, Client(gw.ws_url) as alice, Client(gw.ws_url) as teacher:
        watcher.subscribe(topic, TWIST)
        alice.send({'op': 'advertise', 'topic': topic, 'type': TWIST})
        ping(alice)
        alice.send(command(topic, 0.5, ms()))
        watcher.expect(lambda m: m.get('topic') == topic and not is_zero_twist(m['msg']))
        # made a second before the Stop, delivered after the Take: the gateway places a stamp on its
        # own clock to within the link's fastest trip, which a loaded machine stretches; a second
        # leaves room for that and is still a stalled link's backlog
        held = [command(topic, 0.5, ms() - 1000) for _ in range(3)]
        teacher.publish('/rosgate/control', {'data': 'stop /s01'})
        watcher.expect(lambda m: m.get('topic') == topic and is_zero_twist(m['msg']))
        watcher.seen = []
        alice.publish('/rosgate/control', {'data': 'take /s01'})
        ping(alice)
        alice.send_together(*held)
        ping(alice)
        assert [m for m in received(watcher, topic) if not is_zero_twist(m)] == []
        alice.send(command(topic, 0.3, ms()))
        ping(alice)
        assert [m['linear']['x'] for m in received(watcher, topic)] == [0.3]
