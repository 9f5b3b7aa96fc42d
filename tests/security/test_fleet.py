"""A fleet of gateways on one PostgreSQL (store.fleet, rules.fleet): two real sim gateway processes
with the same --db, --fleet, --auth and data folder (the cookie secret), and clients of each; the
cases are tests/support/fleet.py's (tests/backends/test_fleet_graph.py runs them on one ROS 2 graph)
and tests/support/fleetfaults.py's: a Stop and a logout sent through A while PostgreSQL restarts,
while B's connections are killed, and while B cannot reach the database for 10 s (B's --db goes
through a relay the test can cut).

Each sim gateway has its robots in its own process, so where the robot itself would be shared
(one ROS graph) the test checks what the other gateway does: its client's commands refused, its
zero published on the station's command topic, its seat ended."""

from __future__ import annotations

import pytest

from tests.support import fleet, fleetfaults
from tests.support.pgproxy import Relay
from tests.support.postgres import postgres as postgres_instance

pg = pytest.fixture(scope='module')(postgres_instance)


@pytest.fixture(scope='module')
def postgres(pg):
    return pg.url


@pytest.fixture(scope='module')
def relay(pg):
    relay = Relay(pg.port)
    yield relay
    relay.close()


@pytest.fixture(scope='module')
def pair(launch, tokens_file, postgres, relay, tmp_path_factory):
    """Gateways A and B of one fleet, each with the stations /s01 and /s02 of its own sim; B reaches
    the database through ``relay``."""
    return fleet.start_pair(launch, tokens_file, postgres, str(tmp_path_factory.mktemp('fleet-data')),
                            '--robot', 'turtlesim', '--fleet', '2', b_db=relay.url(postgres))


@pytest.fixture(scope='module')
def faults(pg, relay, pair):
    return fleetfaults.Faults(pg, relay, pair[1])


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


def test_a_station_claimed_through_a_is_given_back_through_b(pair):
    fleetfaults.release_through_the_other_gateway(*pair)


def test_history_is_written_once(pair, postgres):
    fleet.history_once(pair, postgres)


@pytest.mark.parametrize('fault', fleetfaults.FAULTS)
def test_a_stop_through_a_reaches_b_through_a_database_fault(pair, faults, fault):
    fleetfaults.stop_through_a(*pair, faults, fault, fleet.client_follow)


@pytest.mark.parametrize('fault', fleetfaults.FAULTS)
def test_a_logout_through_a_holds_on_b_through_a_database_fault(pair, faults, fault):
    fleetfaults.logout_through_a(*pair, faults, fault)


def test_a_slot_ends_on_b_while_a_still_seats_its_booker(pair, pg):
    fleetfaults.slot_end_while_another_gateway_still_seats(*pair, pg, fleet.client_follow)


def test_a_slot_booked_through_a_ends_on_time_with_a_killed(pair):
    fleet.slot_ends_with_a_killed(*pair, fleet.client_follow)
