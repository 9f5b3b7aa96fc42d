"""PostgreSQL transactions per drive command in a fleet of two gateways (``python -m tests.bench fleet``).

Two sim gateways on one PostgreSQL of the bench's own (Debian's postgresql, tests.support.postgres);
a signed-in student claims /s01 on gateway A and drives it at about 200 commands a second for
6 s. The database's committed transactions (pg_stat_database.xact_commit) in that window are
compared, per second, with the same window without commands: the difference over the commands is
what one command costs the database (the rules check the fleet's in-memory mirror: it should be 0). The
window ends 2.5 s after the last command, as PostgreSQL flushes each backend's counters at most
once a second; the transactions both windows count are the fleet's beats and the history.

Then the one wait a fleet adds: a free lease's first command waits for PostgreSQL's word
(rules.settle). ROUNDS times a second student on gateway B sends a first command on the free /s02
and the time until the gateway says she holds the lease (the command is published then) is taken,
beside a later command of hers (answered from memory), timed with a rosapi call after it."""

from __future__ import annotations

import sys
import tempfile
import time

import sqlalchemy as sa

from tests.support.auth import TOKENS, tokens_toml
from tests.support.postgres import postgres_server
from tests.support.process import GatewayProcess
from tests.support.wsclient import TWIST, Client, twist

FLAGS = ('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--cmd-timeout', '5')
WINDOW = 6.0
ROUNDS = 30


def main(argv: list[str]) -> int:
    folder = tempfile.mkdtemp(prefix='rosgate-fleet-bench-')
    with open(f'{folder}/tokens.toml', 'w') as f:
        f.write(tokens_toml())
    server = postgres_server()
    url = next(server)
    gateways = []
    engine = sa.create_engine(url, poolclass=sa.pool.NullPool)

    def commits() -> int:
        with engine.connect() as c:
            c.execute(sa.text('SELECT pg_stat_clear_snapshot()'))
            return c.execute(sa.text("SELECT xact_commit FROM pg_stat_database WHERE datname = 'rosgate'")).scalar()

    try:
        gateways = [GatewayProcess(*FLAGS, '--auth', f'{folder}/tokens.toml', '--db', url,
                                   env={'XDG_DATA_HOME': folder}) for _ in range(2)]
        with Client(gateways[0].ws_url, TOKENS['operator']) as alice:
            assert alice.call('/s01/fleet/claim')['values']['success']
            drive = {'op': 'publish', 'topic': '/s01/turtle1/cmd_vel', 'type': TWIST, 'msg': twist(1.0)}
            assert alice.refusal(drive) is None

            def window(send: bool) -> tuple[int, float]:
                """(commands sent, transactions a second over the window)."""
                before, start, n = commits(), time.monotonic(), 0
                end = start + WINDOW
                while time.monotonic() < end:
                    if send:
                        alice.publish('/s01/turtle1/cmd_vel', twist(0.5 + (n % 2) * 0.1), TWIST)
                        n += 1
                    time.sleep(0.005)   # the stream's pace
                if send:
                    assert alice.refusal(drive) is None   # every command went through the door
                time.sleep(2.5)         # PostgreSQL's counters are flushed once a second
                return n, (commits() - before - 1) / (time.monotonic() - start)

            n, busy = window(True)
            _, idle = window(False)
        seconds = WINDOW + 2.5
        print(f'{n} commands through gateway A in {WINDOW:g} s: {busy:.2f} PostgreSQL transactions a second '
              f'over the window, {idle:.2f} without commands; per command: {(busy - idle) * seconds / n:+.4f}')
        first, later = first_command_waits(gateways[1])
        print(f'a free lease\'s first command, {ROUNDS} times through gateway B: told it holds the lease after '
              f'{pct(first, 50):.1f} ms (median), {pct(first, 95):.1f} ms (p95), {max(first):.1f} ms (max); a later '
              f'command and a rosapi call after it: {pct(later, 50):.1f} ms (median), {pct(later, 95):.1f} ms (p95)')
    finally:
        for gw in gateways:
            gw.stop()
        engine.dispose()
        next(server, None)
    return 0


def pct(values: list[float], p: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(len(ordered) * p / 100))]


def first_command_waits(gw) -> tuple[list[float], list[float]]:
    """ms until the gateway grants the lease to a first command (waiting for PostgreSQL), and until
    a rosapi call sent after a later command of the same holder is answered (the lease from memory)."""
    first, later = [], []
    topic = '/s02/turtle1/cmd_vel'
    with Client(gw.ws_url, TOKENS['operator2']) as bob:
        bob.send({'op': 'set_level', 'level': 'info'})
        assert bob.refusal({'op': 'advertise', 'topic': topic, 'type': TWIST}) is None
        for n in range(ROUNDS):
            start = time.monotonic()
            bob.publish(topic, twist(0.1), id=f'first:{n}')
            bob.expect(lambda m: 'you hold the driver lease' in m.get('msg', ''), 10)
            first.append((time.monotonic() - start) * 1000)
            start = time.monotonic()   # handled before the rosapi call that follows it is answered
            assert bob.refusal({'op': 'publish', 'topic': topic, 'msg': twist(0.0)}) is None
            later.append((time.monotonic() - start) * 1000)
            bob.publish('/rosgate/control', {'data': 'release /s02'}, 'std_msgs/msg/String')
            time.sleep(0.05)    # the release reaches PostgreSQL before the next first command
    return first, later


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
