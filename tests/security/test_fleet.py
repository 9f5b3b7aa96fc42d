"""A fleet of gateways on one PostgreSQL (store.fleet, rules.fleet): two real sim gateway processes
with the same --db, --fleet, --auth and data folder (the cookie secret), and clients of each; the
cases are tests/support/fleet.py's (tests/backends/test_fleet_graph.py runs them on one ROS 2 graph).

Each sim gateway has its robots in its own process, so where the robot itself would be shared
(one ROS graph) the test checks what the other gateway does: its client's commands refused, its
zero published on the station's command topic, its seat ended."""

from __future__ import annotations

import pytest

from tests.support import fleet
from tests.support.postgres import postgres_server

postgres = pytest.fixture(scope='module')(postgres_server)


@pytest.fixture(scope='module')
def pair(launch, tokens_file, postgres, tmp_path_factory):
    """Gateways A and B of one fleet, each with the stations /s01 and /s02 of its own sim."""
    return fleet.start_pair(launch, tokens_file, postgres, str(tmp_path_factory.mktemp('fleet-data')),
                            '--robot', 'turtlesim', '--fleet', '2')


def test_one_station_one_person_whichever_gateway(pair):
    fleet.one_station_one_person(*pair)


def test_claims_at_the_same_moment_get_one_yes(pair):
    fleet.claims_at_once(*pair)


def test_the_walk_in_line_is_one_for_the_fleet(pair):
    fleet.one_line(*pair)


def test_a_stop_on_a_halts_a_student_driving_through_b(pair):
    fleet.stop_on_a_halts_b(*pair, fleet.client_follow)


def test_a_logout_on_a_ends_the_session_on_b_at_once(pair):
    fleet.logout_everywhere(*pair)


def test_history_is_written_once(pair, postgres):
    fleet.history_once(pair, postgres)


def test_a_slot_booked_through_a_ends_on_time_with_a_killed(pair):
    fleet.slot_ends_with_a_killed(*pair, fleet.client_follow)
