"""A fleet of gateways on one ROS 2 graph (Jazzy, rclpy) and one PostgreSQL: two rclpy gateways,
A and B, with the same --db, --auth and data folder, and the robots of two stations, /s01 and /s02,
on the graph (plain rclpy nodes of their own context: each takes ``turtle1/cmd_vel``, publishes its
odometry and serves ``reset``, std_srvs Empty, the --station-reset of a slot's end). The cases are
tests/support/fleet.py's and fleetfaults.py's: here each robot's own subscription hears what both
gateways send it, so a Stop, a slot's end and two first commands at once are checked where they
matter, at the robot. B reaches the database through a relay the test can cut (the faults: a
PostgreSQL restart, B's connections killed, B cut off for 10 s, each over a slot's end; the Stop
and the logout through the same faults are shown faster by the sim pair, tests/security/test_fleet.py).

On one graph the gateways' own topics are ROS topics: a client of B hears A's /rosgate/stations
announcements as well as B's. So the gateways are ready when each serves the stations' claims
(its /rosapi/services), not when an announcement lists them (that may be the other's)."""

from __future__ import annotations

import threading
import time

import pytest

from tests.support import fleet, fleetfaults
from tests.support.auth import TOKENS
from tests.support.contract import rclpy_missing
from tests.support.http import api
from tests.support.pgproxy import Relay
from tests.support.postgres import postgres as postgres_instance
from tests.support.wait import wait_for
from tests.support.wsclient import Client, is_zero_twist

pytestmark = pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here')

STATIONS = ('/s01', '/s02')
pg = pytest.fixture(scope='module')(postgres_instance)


class Robots:
    """The stations' robots in one rclpy context of their own, spun in a thread: each keeps the
    velocity commands it receives, in order, as the dicts a rosbridge client would get."""

    def __init__(self):
        import rclpy
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        from std_srvs.srv import Empty

        self.context = Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.received = {ns: [] for ns in STATIONS}
        self.resets = {ns: 0 for ns in STATIONS}       # calls of each station's reset service
        self.changed = threading.Condition()
        self.nodes = []
        for ns in STATIONS:
            node = rclpy.create_node('turtlesim', namespace=ns, context=self.context)
            node.create_subscription(Twist, 'turtle1/cmd_vel', lambda msg, ns=ns: self._take(ns, msg), 100)
            odom = node.create_publisher(Odometry, 'odom', 10)
            node.create_timer(0.5, lambda odom=odom: odom.publish(Odometry()))   # what the history keeps
            node.create_service(Empty, 'reset', lambda request, response, ns=ns: self._reset(ns, response))
            self.executor.add_node(node)
            self.nodes.append(node)
        self.thread = threading.Thread(target=self.executor.spin, name='fleet-robots', daemon=True)
        self.thread.start()

    def _take(self, ns: str, msg) -> None:
        as_dict = {part: {axis: getattr(getattr(msg, part), axis) for axis in 'xyz'} for part in ('linear', 'angular')}
        with self.changed:
            self.received[ns].append(as_dict)
            self.changed.notify_all()

    def _reset(self, ns: str, response):
        with self.changed:
            self.resets[ns] += 1
            self.changed.notify_all()
        return response

    def follow(self, _watcher, ns: str):
        """tests.support.fleet's ``follow``: the commands the robot of ``ns`` receives from now on."""
        with self.changed:
            seen = len(self.received[ns])

        def heard(predicate, timeout: float) -> dict:
            nonlocal seen
            deadline = time.monotonic() + timeout
            with self.changed:
                while True:
                    for msg in self.received[ns][seen:]:
                        seen += 1
                        if predicate(msg):
                            return msg
                    left = deadline - time.monotonic()
                    if left <= 0:
                        raise AssertionError(f'{ns}: no matching command within {timeout} s; '
                                             f'last received {self.received[ns][-3:]}')
                    self.changed.wait(left)
        return heard

    def stop(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        for node in self.nodes:
            node.destroy_node()
        self.context.try_shutdown()
        self.thread.join(timeout=2.0)


@pytest.fixture(scope='module')
def robots(rclpy_helpers):
    robots = Robots()
    yield robots
    robots.stop()


@pytest.fixture(scope='module')
def postgres(pg):
    return pg.url


@pytest.fixture(scope='module')
def relay(pg):
    relay = Relay(pg.port)
    yield relay
    relay.close()


@pytest.fixture(scope='module')
def data(tmp_path_factory):
    return str(tmp_path_factory.mktemp('fleet-data'))


FLAGS = ('--backend', 'rclpy', '--station-reset', 'reset')


def serving(gw) -> None:
    """Wait until ``gw`` serves both stations' claims (its /rosapi/services: not /rosgate/stations,
    which on one graph carries every gateway's announcements, so that one gateway's list may stand
    for another's)."""
    claims = {f'{ns}/fleet/claim' for ns in STATIONS}
    with Client(gw.ws_url, TOKENS['viewer']) as c:
        wait_for(lambda: claims <= set(c.call('/rosapi/services')['values']['services']), 30, 0.1,
                 what=f'{gw.node} serves both stations')


@pytest.fixture(scope='module')
def pair(robots, launch, tokens_file, postgres, relay, data):
    """Gateways A and B on the graph, each once it serves both stations' claims; B reaches the
    database through ``relay``."""
    gateways = fleet.start_pair(launch, tokens_file, postgres, data, *FLAGS, b_db=relay.url(postgres))
    for gw in gateways:
        serving(gw)
    return gateways


@pytest.fixture(scope='module')
def faults(pg, relay, pair):
    return fleetfaults.Faults(pg, relay, pair[1])


def test_one_station_one_person_whichever_gateway(pair):
    fleet.one_station_one_person(*pair)


def test_claims_at_the_same_moment_get_one_yes(pair):
    fleet.claims_at_once(*pair)


def test_a_stop_on_a_halts_at_the_robot_a_student_driving_through_b(pair, robots):
    fleet.stop_on_a_halts_b(*pair, robots.follow)


def test_a_logout_on_a_ends_the_session_on_b_at_once(pair):
    fleet.logout_everywhere(*pair)


def test_history_is_written_once(pair, postgres):
    fleet.history_once(pair, postgres)


def test_two_first_commands_at_once_one_driver_fifty_times(pair, robots):
    """Neither student claimed: both publish their first command on the free /s01 at the same
    instant through A and B. 50 times: one driver, and nothing of the other's at the robot."""
    settled = lambda: sum(gw.log_text().count('driver lease for /s01: PostgreSQL gave it') for gw in pair)  # noqa: E731
    before = settled()
    wins = fleetfaults.first_commands_at_once(*pair, lambda ns: robots.received[ns], rounds=50)
    print(f'\n50 rounds of two first commands at once: alice (A) won {wins["alice"]}, bob (B) {wins["bob"]}; '
          f'in {settled() - before} both asked PostgreSQL (the others: the loser\'s gateway knew already)')


def reset_decisions(pair) -> int:
    """How many times the gateways decided a /s01 reset at a slot's end (done, or left to another)."""
    return sum(gw.log_text().count('slot end: /s01 reset') for gw in pair)


@pytest.mark.parametrize('fault', fleetfaults.FAULTS)
def test_a_slot_ends_and_its_station_is_reset_once_through_a_database_fault(pair, robots, faults, fault):
    """A slot booked through A for alice, who drives through B; the fault over its end. Her commands
    are refused when it ends (each gateway's own timer: no database needed), the robot gets its
    zero, and the station's reset is called once: by whichever gateway claimed it first in the
    database, the other saying so (a gateway cut off learns it when it can read again)."""
    a, b = pair
    with Client(a.ws_url, TOKENS['admin']) as teacher, Client(b.ws_url, TOKENS['operator']) as alice, \
            Client(b.ws_url, TOKENS['viewer']) as watcher:
        begin = time.time() + 2
        status, slot = api(a, 'POST', '/api/bookings', {'station': '/s01', 'start': begin, 'end': begin + 5,
                                                        'for': 'alice'}, token=TOKENS['admin'])
        assert status == 201, slot
        fleet.stations(watcher)
        wait_for(lambda: fleet.owner_on(watcher, '/s01') == 'alice', 30, 0.0, what='alice seated at /s01')
        heard = robots.follow(watcher, '/s01')
        decided, resets = reset_decisions(pair), robots.resets['/s01']
        stream = fleetfaults.Stream(alice, '/s01')
        try:
            heard(lambda m: m['linear']['x'] == 1.0, 15)
            wait_for(lambda: time.time() > slot['end'] - 1, 30, 0.02, what='a second before the slot ends')
            with faults.during(fault):
                fleetfaults.refusal_with(alice, 'slot on /s01 has ended')
                heard(is_zero_twist, 15)
        finally:
            stream.stop()
        wait_for(lambda: reset_decisions(pair) >= decided + 2, 60, 0.1, what='both gateways decided the reset')
        assert robots.resets['/s01'] == resets + 1, robots.resets
        print(f'\n{fault}: the slot ended and /s01 was reset once; both gateways had decided '
              f'{time.time() - slot["end"]:.2f} s after its end')
        teacher.call('/s01/fleet/release')


def test_a_gateway_started_after_a_stop_honours_it(pair, robots, launch, tokens_file, postgres, data):
    def start_c():
        return launch(*fleet.FLAGS, *FLAGS, '--auth', tokens_file, '--db', postgres, env={'XDG_DATA_HOME': data})
    fleetfaults.stop_known_to_a_later_gateway(pair[0], start_c, robots.follow)


def test_a_slot_booked_through_a_ends_on_time_with_a_killed(pair, robots):
    fleet.slot_ends_with_a_killed(*pair, robots.follow)
