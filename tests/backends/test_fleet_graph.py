"""A fleet of gateways on one ROS 2 graph (Jazzy, rclpy) and one PostgreSQL: two rclpy gateways,
A and B, with the same --db, --auth and data folder, and the robots of two stations, /s01 and /s02,
on the graph (plain rclpy nodes of their own context: each takes ``turtle1/cmd_vel`` and publishes
its odometry). The cases are tests/support/fleet.py's: here each robot's own subscription hears
what both gateways send it, so a Stop or a slot's end is checked where it matters, at the robot.

On one graph the gateways' own topics are ROS topics: a client of B hears A's /rosgate/stations
announcements as well as B's. So the gateways are ready when each serves the stations' claims
(its /rosapi/services), not when an announcement lists them (that may be the other's)."""

from __future__ import annotations

import threading
import time

import pytest

from tests.support import fleet
from tests.support.auth import TOKENS
from tests.support.contract import rclpy_missing
from tests.support.postgres import postgres_server
from tests.support.wait import wait_for
from tests.support.wsclient import Client

pytestmark = pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here')

STATIONS = ('/s01', '/s02')
postgres = pytest.fixture(scope='module')(postgres_server)


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

        self.context = Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.received = {ns: [] for ns in STATIONS}
        self.changed = threading.Condition()
        self.nodes = []
        for ns in STATIONS:
            node = rclpy.create_node('turtlesim', namespace=ns, context=self.context)
            node.create_subscription(Twist, 'turtle1/cmd_vel', lambda msg, ns=ns: self._take(ns, msg), 100)
            odom = node.create_publisher(Odometry, 'odom', 10)
            node.create_timer(0.5, lambda odom=odom: odom.publish(Odometry()))   # what the history keeps
            self.executor.add_node(node)
            self.nodes.append(node)
        self.thread = threading.Thread(target=self.executor.spin, name='fleet-robots', daemon=True)
        self.thread.start()

    def _take(self, ns: str, msg) -> None:
        as_dict = {part: {axis: getattr(getattr(msg, part), axis) for axis in 'xyz'} for part in ('linear', 'angular')}
        with self.changed:
            self.received[ns].append(as_dict)
            self.changed.notify_all()

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
def pair(robots, launch, tokens_file, postgres, tmp_path_factory):
    """Gateways A and B on the graph, each once it serves both stations' claims (its
    /rosapi/services: not /rosgate/stations, which on one graph carries every gateway's
    announcements, so that one gateway's list may stand for another's)."""
    gateways = fleet.start_pair(launch, tokens_file, postgres, str(tmp_path_factory.mktemp('fleet-data')),
                                '--backend', 'rclpy')
    claims = {f'{ns}/fleet/claim' for ns in STATIONS}
    for gw in gateways:
        with Client(gw.ws_url, TOKENS['viewer']) as c:
            wait_for(lambda: claims <= set(c.call('/rosapi/services')['values']['services']), 20, 0.1,
                     what=f'{gw.node} serves both stations')
    return gateways


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


def test_a_slot_booked_through_a_ends_on_time_with_a_killed(pair, robots):
    fleet.slot_ends_with_a_killed(*pair, robots.follow)
