"""The rules: who may do what, and keeping robots safe.

Rooms: name globs, the Host/Origin checks and a trusted proxy's forwarded headers (``names``);
roles, caps and op rate (``policy``: one policy, reading who someone is from ``auth``: tokens,
sign-in sessions, LTI identities); the one access rule, "may this identity read/write/call/own
this", for every path (``access``); refusals that carry their HTTP status (``errors``); robot
stations and the person who owns each (``stations``), the walk-ins' line (``queue``), booked slots
(``bookings``); the driver lease per station (``lease``); velocity clamps and stops (``safety``);
a stamped command's age (``freshness``); the events the gateway's parts follow (``hooks``).

``add_arguments(parser)`` adds their flags (each flag's field is in ``gateway.settings``);
``load(settings)`` reads their files once at start-up (``ConfigError`` naming the flag);
``compose(doors, files, reads, runs)`` builds them all, in the one order of ``compose``'s
docstring, each part given the few doors it uses (``ports``; ``doors``: ``bridge.doors.RuleDoors``),
and ``Gateway.install`` puts the result in force.

May import: ``protocol`` and ``backends`` (for QoS and types), ``auth``, ``store`` and ``settings``,
never ``bridge`` or ``web``: the doors are handed in (``ports``), never the Gateway.
"""

from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple


from .access import StationGrants
from .attempts import AttemptRule
from .bookings import BookingLimits, Slots, Timetable
from .fleet import FleetPart
from .hooks import Hook, Hooks  # noqa: F401 (for the bridge and web)
from .lease import Lease
from .names import parse_globs, parse_networks
from .policy import GATEWAY_ROLE, Limits, SecurePolicy  # noqa: F401 (GATEWAY_ROLE: for the bridge)
from .ports import RuleDoors
from .queue import Queue
from .reports import Reports
from .safety import Clamp, Safety, VelocityLimits
from ..auth.lti import LtiConfig
from ..auth.sessions import Sessions, cookie_secret
from .stations import Stations
from .stops import Stops
from ..auth.tokens import Authenticator, Brake, TokenStore
from ..settings import SafetySettings
from ..store.fleet import Fleet

log = logging.getLogger('rosgate.security')


def _positive(kind):
    def parse(text: str):
        value = kind(text)
        if value < 0:
            raise argparse.ArgumentTypeError(f'{text} is negative')
        return value
    return parse


def _names(text: str) -> list[str]:
    return [t.strip() for t in text.split(',') if t.strip()]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group('access control')
    g.add_argument('--auth', dest='security.auth', metavar='TOKENS.toml', type=Path,
                   help='require a token: a TOML file mapping tokens to roles viewer/operator/admin')
    g.add_argument('--auth-backoff', dest='security.auth_backoff', type=_positive(float), metavar='S',
                   help='after 3 failed attempts from an address, wait this long, doubling each failure '
                        '(up to 30 s) [%(default)s]')
    g.add_argument('--session-hours', dest='security.session_hours', type=_positive(float), metavar='H',
                   help='a sign-in (/login or an LMS launch) lasts this long; /logout ends it at once [%(default)s]')
    g.add_argument('--lti', dest='security.lti', metavar='TOOL.json', type=Path,
                   help='launch from an LMS (LTI 1.3): platforms and deployments in PyLTI1p3\'s tool '
                        'configuration JSON; see /lti/config')
    g.add_argument('--trusted-proxies', dest='security.trusted_proxies', metavar='ADDRS',
                   help='addresses or networks of TLS reverse proxies whose X-Forwarded-Proto/Host/For are '
                        'believed, e.g. "127.0.0.1,10.0.0.0/8" (others\' are ignored)')
    g.add_argument('--max-subscriptions', dest='security.max_subscriptions', type=_positive(int),
                   help='topics one client may subscribe to [%(default)s]')
    g.add_argument('--max-publishers', dest='security.max_publishers', type=_positive(int),
                   help='topics one client may advertise [%(default)s]')
    g.add_argument('--max-pending-calls', dest='security.max_pending_calls', type=_positive(int),
                   help='service calls and action goals one client may have in flight [%(default)s]')
    g.add_argument('--max-op-rate', dest='security.max_op_rate', type=_positive(float), metavar='OPS',
                   help='incoming ops per second per client, 0 for no limit [%(default)s]')
    s = parser.add_argument_group('safety of live control')
    s.add_argument('--stop-on-disconnect', dest='safety.stop_on_disconnect', action=argparse.BooleanOptionalAction,
                   help='publish a zero command when a client that was driving goes away [on]')
    s.add_argument('--stop-types', dest='safety.stop_types', type=_names, metavar='TYPES',
                   help=f"velocity command types, comma-separated [{','.join(SafetySettings.stop_types)}]")
    s.add_argument('--cmd-timeout', dest='safety.cmd_timeout', type=_positive(float), metavar='S',
                   help='zero a command stream that goes silent this long, 0 for never [%(default)s]')
    s.add_argument('--cmd-max-age', dest='safety.cmd_max_age', type=_positive(float), metavar='S',
                   help='drop a stamped moving command that waited this long beyond its link\'s fastest trip '
                        '(a stalled link\'s backlog), 0 for never; see docs/protocol.md [%(default)s]')
    s.add_argument('--require-cmd-stamp', dest='safety.require_cmd_stamp', action='store_true',
                   help='refuse moving velocity commands that carry no stamp ("t" on publish); without it '
                        'plain rosbridge clients\' commands pass as they always did')
    s.add_argument('--max-linear', dest='safety.max_linear', type=_positive(float), metavar='M/S', help='clamp linear velocity')
    s.add_argument('--max-angular', dest='safety.max_angular', type=_positive(float), metavar='RAD/S', help='clamp angular velocity')
    s.add_argument('--velocity-limits', dest='safety.velocity_limits', metavar='LIMITS.toml', type=Path,
                   help='per-topic clamps ([[limits]] tables with topic, max_linear, max_angular)')
    s.add_argument('--exclusive-control', dest='safety.exclusive_control', action='store_true',
                   help='one client at a time drives each robot (fleet station, robot namespace or '
                        '--control-glob group); see /rosgate/driver and /rosgate/control')
    s.add_argument('--control-glob', dest='safety.control_glob', help='more names under the driver lease besides velocity topics, each '
                                          'glob its own lease, e.g. "[\'/turtle1/*\', \'/turtle2/*\']"')
    c = parser.add_argument_group('stations (a class on --fleet N, or robots in their own namespaces)')
    c.add_argument('--claim-idle', dest='stations.claim_idle', type=_positive(float), metavar='S',
                   help='a station stays its owner\'s (through reloads, closed tabs, sleeping tablets) until '
                        'released, or until none of the owner\'s pages has been connected this long [%(default)s]')
    b = parser.add_argument_group('bookings (slots per station, booked ahead; the gateway ends each on time)')
    b.add_argument('--booking', dest='lab.booking', action='store_true',
                   help='stations are booked ahead in slots (/api/bookings); during a slot the station is its '
                        'booker\'s, and at its end the gateway stops it, frees it and resets it')
    b.add_argument('--slot-minutes', dest='lab.slot_minutes', type=_positive(float), metavar='MIN',
                   help='the longest slot, in minutes (fractions allowed) [%(default)s]')
    b.add_argument('--booking-per-day', dest='lab.booking_per_day', type=_positive(int), metavar='N',
                   help='slots one person may book per day, admins excepted, 0 for no limit [%(default)s]')
    b.add_argument('--booking-per-week', dest='lab.booking_per_week', type=_positive(int), metavar='N',
                   help='slots one person may book per week, admins excepted, 0 for no limit [%(default)s]')
    b.add_argument('--booking-ahead', dest='lab.booking_ahead', type=_positive(float), metavar='DAYS',
                   help='how far ahead a slot may be booked, in days, 0 for no limit [%(default)s]')
    b.add_argument('--station-reset', dest='lab.station_reset', metavar='NAME',
                   help='at a slot\'s end, call this service (std_srvs Empty or Trigger) in the station\'s '
                        'namespace, e.g. "reset" (turtlesim) or "reset_world"')
    c.add_argument('--claim-grace', dest='stations.claim_grace', type=_positive(float), metavar='S',
                   help='a station claimed by a client with no name and no browser id (a script) stays its '
                        'own this long after it leaves [%(default)s]')


class ConfigError(ValueError):
    """A flag whose value cannot be used; ``flags`` names it (the CLI refuses to start)."""

    def __init__(self, flags: str, message: str):
        super().__init__(f'{flags}: {message}')
        self.flags, self.why = flags, message


class Files(NamedTuple):
    """The rules' configuration files, read once at start-up."""
    tokens: TokenStore | None = None
    lti: LtiConfig | None = None
    velocity: VelocityLimits | None = None


def load(settings) -> Files:
    """Reads and checks the files and values the rules' flags name; a ConfigError names the flag."""
    sec, safety = settings.security, settings.safety

    def read(flag, loader, path):
        if path is None:
            return None
        try:
            return loader(path)
        except (OSError, ValueError) as e:    # tomllib.TOMLDecodeError is a ValueError
            raise ConfigError(flag, str(e)) from None

    read('--trusted-proxies', parse_networks, sec.trusted_proxies)
    for flag, value in (('--control-glob', safety.control_glob), ('--allowed-hosts', settings.allowed_hosts),
                        ('--allowed-origins', settings.allowed_origins)):
        read(flag, parse_globs, value)
    return Files(read('--auth', TokenStore.load, sec.auth), read('--lti', LtiConfig.load, sec.lti),
                 read('--velocity-limits', VelocityLimits.load, safety.velocity_limits))


@dataclass(frozen=True)
class Rules:
    """The rules in force (``compose``): the policy in front of every op, the publish door's
    rules in their order, the op guards, and the parts that follow the gateway's events."""
    policy: SecurePolicy
    publish: tuple            # (sender, SharedPublisher, msg, issued) -> msg, or None to drop; may raise
    guards: tuple             # (session, op) -> None, or raise ProtocolError to refuse the op
    hooks: tuple              # Hook parts, in the order they hear each event
    safety: Safety
    stations: Stations
    lease: Lease | None = None
    slots: Slots | None = None
    lti: LtiConfig | None = None
    fleet: Fleet | None = None    # with --db on PostgreSQL: the other gateways (store.fleet)
    reports: Reports | None = None   # the program reports' stamp and readers (rules.reports)
    attempts: AttemptRule | None = None   # live exercise attempts' stations (rules.attempts)


def compose(doors: RuleDoors, files: Files = Files(), *, reads=lambda name: False, runs=None,
            attempts=None, keepers: tuple = ()) -> Rules:
    """Every rule, built from the settings, in the one order they apply.

    At the publish door (``Gateway.publish``), in this order: (0) a live exercise attempt's pose and
    scan topics are the robot's alone and its station the attempter's (``attempts``), (1) the runs' guard (``runs``: a run
    publishes nothing its starter's station does not own, and its output topics are its own), (2) the
    driver lease (``--exclusive-control``: a command from someone not holding the group's lease is
    refused, and so is a message on a station's other topics, ``stationnames``), (3) program reports
    stamped (``reports``), (4) safety (clamps, stamps, stream tracking for the stops) last, so a clamp
    acts on what will be published. The keepers of names (``access.KEEPERS``), asked by ``may`` on
    every door after the role and the globs: the runs' and the exercises' (``keepers``, from outside
    the rules), the program reports', the stations' (with the lease). Hooks
    hear events in the order: stations, lease, safety, slots, runs (so a slot's end stops a
    station's commands before its run is stopped).

    doors: what the parts are given (``ports.RuleDoors``: the settings, store, backend, hooks, the
    gateway's own topics and services, its publish door, who is there; ``Gateway.rule_doors()``).
    reads: the gateway's own read-only services (rosapi), which viewers may call. runs: the run
    manager (its ``publish_hook``), or None. attempts: () -> the live exercise attempts (the
    exercises' checker), whose stations ``rules.attempts`` keeps: first at the door and a keeper.
    keepers: more (who, action, name) -> why not, from outside the rules (the runs').
    """
    settings, backend = doors.settings, doors.backend
    sec, safe, st, lab = settings.security, settings.safety, settings.stations, settings.lab
    types = tuple(safe.stop_types)
    velocity = VelocityLimits(Clamp(safe.max_linear, safe.max_angular), files.velocity.topics if files.velocity else [])
    safety = Safety(door=doors.door, parties=doors.parties, messages=backend, types=types,
                    stop_on_disconnect=safe.stop_on_disconnect, cmd_timeout=safe.cmd_timeout, limits=velocity,
                    cmd_max_age=safe.cmd_max_age, require_stamp=safe.require_cmd_stamp)

    db = settings.storage.db_url or ''
    fleet = Fleet.of(doors.store) if db.startswith('postgresql') else None   # the other gateways, given to each rule
    auth = sessions = None
    if files.tokens is not None or files.lti is not None:
        store = files.tokens if files.tokens is not None else TokenStore([])   # only LMS launches sign in
        auth = Authenticator(store, Brake(base=sec.auth_backoff))
        # a sign-in ended: its websockets close (here, and on each gateway that applies it: bridge.doors)
        sessions = Sessions(doors.store, cookie_secret(), hours=sec.session_hours, fleet=fleet, events=doors.hooks,
                            still_valid=lambda s: s.kind != 'token' or s.identity.listed(store.entries))
    timetable = None
    if lab.booking:
        timetable = Timetable(doors.store, BookingLimits(
            slot=lab.slot_minutes * 60, per_day=lab.booking_per_day, per_week=lab.booking_per_week,
            ahead=lab.booking_ahead * 86400), events=doors.hooks, fleet=fleet)
    queue = Queue(timetable, grace=st.claim_grace, fleet=fleet) if timetable is not None else None
    lease = None   # the lease, made below, asks the stations who owns what; they ask it through lambda: lease
    stations = Stations(announce=doors.announce, graph=backend, parties=doors.parties, lease=lambda: lease,
                        types=frozenset(types), idle=st.claim_idle, grace=st.claim_grace,
                        grants=StationGrants(auth is not None), timetable=timetable, queue=queue, fleet=fleet)
    stops = Stops(safety=safety, parties=doors.parties, graph=backend, events=doors.hooks, stations=stations)
    if safe.exclusive_control:
        lease = Lease(announce=doors.announce, control=backend, types=frozenset(types), globs=parse_globs(safe.control_glob),
                      grants=StationGrants(auth is not None), stations=stations, stops=stops, fleet=fleet)
    limits = Limits(max_subscriptions=sec.max_subscriptions, max_publishers=sec.max_publishers,
                    max_pending_calls=sec.max_pending_calls, max_op_rate=sec.max_op_rate)
    reports = Reports(stations, auth=auth is not None)
    live = AttemptRule(attempts, lease=lease, stations=stations) if attempts is not None else None
    keepers = (*keepers, *((live.keeper,) if live is not None else ()), reports.keeper,
               *((lease.names.name_refusal,) if lease is not None else ()))
    policy = SecurePolicy(settings, auth=auth, limits=limits, lease=lease, stations=stations, reads=reads,
                          sessions=sessions, keepers=keepers)
    slots = None
    if timetable is not None:
        if lease is None:
            log.warning('--booking without --exclusive-control: slots seat their bookers and end on time, but '
                        'nothing keeps others\' commands off a booked robot')
        slots = Slots(timetable, events=doors.hooks, caller=backend, stations=stations, lease=lease,
                      stops=stops, reset=lab.station_reset, queue=queue)
    part = None
    if fleet is not None:
        part = FleetPart(fleet, lease=lease, stations=stations, sessions=sessions, timetable=timetable)
        part.start()

    publish = (*((live.publish_hook,) if live is not None else ()), *((runs.publish_hook,) if runs is not None else ()),
               *((lease.publish_hook,) if lease is not None else ()), reports.publish_hook, safety.publish_hook)
    guards = ()
    signouts = doors.signouts if sessions is not None else None
    hooks = tuple(h for h in (stations, lease, safety, slots, runs, part, signouts) if h is not None)
    log.info('security: auth %s, exclusive control %s, stop on disconnect %s, cmd timeout %s s, '
             'cmd max age %s s%s', 'on' if auth else 'off', 'on' if lease else 'off', safety.stop_on_disconnect,
             safety.cmd_timeout, safety.cmd_max_age, ', stamps required' if safety.require_stamp else '')
    return Rules(policy=policy, publish=publish, guards=guards, hooks=hooks, safety=safety, stations=stations,
                 lease=lease, slots=slots, lti=files.lti, fleet=fleet, reports=reports, attempts=live)
