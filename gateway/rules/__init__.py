"""The rules: who may do what, and keeping robots safe.

Name globs, the Host/Origin checks and a trusted proxy's forwarded headers (``names``), roles,
tokens, caps and op rate (``policy``, ``tokens``: one policy), sign-in sessions kept in the store
(``sessions``), who an LMS launch says someone is and whether to believe it (``lti``), robot stations and the person who owns each (``stations``), the driver
lease per station (``lease``), velocity clamps and stops (``safety``). ``add_arguments(parser)`` adds their flags; ``install(gateway, reads)`` puts the
policy in front of every op and the lease and safety at the publish door (``Gateway.publish``).

May import: ``protocol`` and ``backends`` (for QoS and types), ``store`` (sessions) and ``settings``,
never ``bridge`` or ``web``: the gateway is handed in.
"""

from __future__ import annotations

import argparse
import logging

from .bookings import BookingLimits, Slots, Timetable
from .lease import Lease
from .names import parse_globs, parse_networks
from .policy import GATEWAY_ROLE, Limits, SecurePolicy  # noqa: F401 (GATEWAY_ROLE: for the bridge)
from .queue import Queue
from .safety import CMD_MAX_AGE, DEFAULT_TYPES, Clamp, Safety, VelocityLimits
from .lti import LtiConfig
from .sessions import DEFAULT_HOURS, Sessions, cookie_secret
from .stations import CLAIM_GRACE, CLAIM_IDLE, Stations
from .tokens import Authenticator, Brake, TokenStore

log = logging.getLogger('rosgate.security')


def _positive(kind):
    def parse(text: str):
        value = kind(text)
        if value < 0:
            raise argparse.ArgumentTypeError(f'{text} is negative')
        return value
    return parse


def _loaded(load):
    """Read a config file while parsing flags, so a mistake is a usage error naming the file."""
    def parse(path: str):
        try:
            return load(path)
        except (OSError, ValueError) as e:   # tomllib.TOMLDecodeError is a ValueError
            raise argparse.ArgumentTypeError(str(e)) from None
    return parse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    d = Limits()
    g = parser.add_argument_group('access control')
    g.add_argument('--auth', metavar='TOKENS.toml', type=_loaded(TokenStore.load),
                   help='require a token: a TOML file mapping tokens to roles viewer/operator/admin')
    g.add_argument('--auth-backoff', type=_positive(float), default=0.5, metavar='S',
                   help='after 3 failed attempts from an address, wait this long, doubling each failure '
                        '(up to 30 s) [%(default)s]')
    g.add_argument('--session-hours', type=_positive(float), default=DEFAULT_HOURS, metavar='H',
                   help='a sign-in (/login or an LMS launch) lasts this long; /logout ends it at once [%(default)s]')
    g.add_argument('--lti', metavar='TOOL.json', type=_loaded(LtiConfig.load),
                   help='launch from an LMS (LTI 1.3): platforms and deployments in PyLTI1p3\'s tool '
                        'configuration JSON; see /lti/config')
    g.add_argument('--trusted-proxies', metavar='ADDRS', type=_loaded(lambda v: parse_networks(v) and v),
                   help='addresses or networks of TLS reverse proxies whose X-Forwarded-Proto/Host/For are '
                        'believed, e.g. "127.0.0.1,10.0.0.0/8" (others\' are ignored)')
    g.add_argument('--max-subscriptions', type=_positive(int), default=d.max_subscriptions,
                   help='topics one client may subscribe to [%(default)s]')
    g.add_argument('--max-publishers', type=_positive(int), default=d.max_publishers,
                   help='topics one client may advertise [%(default)s]')
    g.add_argument('--max-pending-calls', type=_positive(int), default=d.max_pending_calls,
                   help='service calls and action goals one client may have in flight [%(default)s]')
    g.add_argument('--max-op-rate', type=_positive(float), default=d.max_op_rate, metavar='OPS',
                   help='incoming ops per second per client, 0 for no limit [%(default)s]')
    s = parser.add_argument_group('safety of live control')
    s.add_argument('--stop-on-disconnect', action=argparse.BooleanOptionalAction, default=True,
                   help='publish a zero command when a client that was driving goes away [on]')
    s.add_argument('--stop-types', default=','.join(DEFAULT_TYPES),
                   help='velocity command types [%(default)s]')
    s.add_argument('--cmd-timeout', type=_positive(float), default=1.0, metavar='S',
                   help='zero a command stream that goes silent this long, 0 for never [%(default)s]')
    s.add_argument('--cmd-max-age', type=_positive(float), default=CMD_MAX_AGE, metavar='S',
                   help='drop a stamped moving command that waited this long beyond its link\'s fastest trip '
                        '(a stalled link\'s backlog), 0 for never; see docs/protocol.md [%(default)s]')
    s.add_argument('--require-cmd-stamp', action='store_true',
                   help='refuse moving velocity commands that carry no stamp ("t" on publish); without it '
                        'plain rosbridge clients\' commands pass as they always did')
    s.add_argument('--max-linear', type=_positive(float), metavar='M/S', help='clamp linear velocity')
    s.add_argument('--max-angular', type=_positive(float), metavar='RAD/S', help='clamp angular velocity')
    s.add_argument('--velocity-limits', metavar='LIMITS.toml', type=_loaded(VelocityLimits.load),
                   help='per-topic clamps ([[limits]] tables with topic, max_linear, max_angular)')
    s.add_argument('--exclusive-control', action='store_true',
                   help='one client at a time drives each robot (fleet station, robot namespace or '
                        '--control-glob group); see /rosgate/driver and /rosgate/control')
    s.add_argument('--control-glob', help='more names under the driver lease besides velocity topics, each '
                                          'glob its own lease, e.g. "[\'/turtle1/*\', \'/turtle2/*\']"')
    c = parser.add_argument_group('stations (a class on --fleet N, or robots in their own namespaces)')
    c.add_argument('--claim-idle', type=_positive(float), default=CLAIM_IDLE, metavar='S',
                   help='a station stays its owner\'s (through reloads, closed tabs, sleeping tablets) until '
                        'released, or until none of the owner\'s pages has been connected this long [%(default)s]')
    b = parser.add_argument_group('bookings (slots per station, booked ahead; the gateway ends each on time)')
    dl = BookingLimits()
    b.add_argument('--booking', action='store_true',
                   help='stations are booked ahead in slots (/api/bookings); during a slot the station is its '
                        'booker\'s, and at its end the gateway stops it, frees it and resets it')
    b.add_argument('--slot-minutes', type=_positive(float), default=dl.slot / 60, metavar='MIN',
                   help='the longest slot, in minutes (fractions allowed) [%(default)s]')
    b.add_argument('--booking-per-day', type=_positive(int), default=dl.per_day, metavar='N',
                   help='slots one person may book per day, admins excepted, 0 for no limit [%(default)s]')
    b.add_argument('--booking-per-week', type=_positive(int), default=dl.per_week, metavar='N',
                   help='slots one person may book per week, admins excepted, 0 for no limit [%(default)s]')
    b.add_argument('--booking-ahead', type=_positive(float), default=dl.ahead / 86400, metavar='DAYS',
                   help='how far ahead a slot may be booked, in days, 0 for no limit [%(default)s]')
    b.add_argument('--station-reset', metavar='NAME',
                   help='at a slot\'s end, call this service (std_srvs Empty or Trigger) in the station\'s '
                        'namespace, e.g. "reset" (turtlesim) or "reset_world"')
    c.add_argument('--claim-grace', type=_positive(float), default=CLAIM_GRACE, metavar='S',
                   help='a station claimed by a client with no name and no browser id (a script) stays its '
                        'own this long after it leaves [%(default)s]')


def install(gateway, reads=lambda name: False) -> None:
    """reads: the gateway's own read-only services (rosapi), which viewers may call."""
    settings, extra = gateway.settings, gateway.settings.extra
    types = tuple(t.strip() for t in (extra.get('stop_types') or ','.join(DEFAULT_TYPES)).split(',') if t.strip())
    per_topic = extra.get('velocity_limits')
    velocity = VelocityLimits(Clamp(extra.get('max_linear'), extra.get('max_angular')),
                              per_topic.topics if per_topic else [])
    safety = Safety(gateway, types=types, stop_on_disconnect=extra.get('stop_on_disconnect', True),
                    cmd_timeout=extra.get('cmd_timeout', 1.0), limits=velocity,
                    cmd_max_age=extra.get('cmd_max_age', CMD_MAX_AGE),
                    require_stamp=extra.get('require_cmd_stamp', False))

    auth = sessions = None
    if extra.get('auth') or extra.get('lti'):
        if extra.get('auth'):
            store = extra['auth'] if isinstance(extra['auth'], TokenStore) else TokenStore.load(extra['auth'])
        else:
            store = TokenStore([])   # only LMS launches sign in
        auth = Authenticator(store, Brake(base=extra.get('auth_backoff', 0.5)))
        sessions = Sessions(gateway.store, cookie_secret(), hours=extra.get('session_hours', DEFAULT_HOURS),
                            still_valid=lambda s: s.kind != 'token' or s.identity.listed(store.entries))
    timetable = None
    if extra.get('booking'):
        d = BookingLimits()
        timetable = Timetable(gateway.store, BookingLimits(
            slot=float(extra.get('slot_minutes', d.slot / 60)) * 60, per_day=extra.get('booking_per_day', d.per_day),
            per_week=extra.get('booking_per_week', d.per_week),
            ahead=float(extra.get('booking_ahead', d.ahead / 86400)) * 86400))
    queue = Queue(timetable, grace=extra.get('claim_grace', CLAIM_GRACE)) if timetable is not None else None
    stations = Stations(gateway, types=frozenset(types), idle=extra.get('claim_idle', CLAIM_IDLE),
                        grace=extra.get('claim_grace', CLAIM_GRACE), admin_role='admin' if auth else None,
                        timetable=timetable, queue=queue)
    lease = None

    def group_of(topic):
        return lease.group(topic) if lease is not None else next(
            (ns for ns in stations.stations() if topic.startswith(ns + '/')), '/')

    def in_group(group):
        return lambda topic: group_of(topic) == group

    def stop_group(group):
        """The teacher's Stop and a slot's end: every command left moving in the group is zeroed,
        what else publishes into it (playbacks) ends."""
        for session in gateway.everyone():
            safety.stop_session(session, in_group(group))
        for hook in gateway.hooks:
            stopped = getattr(hook, 'on_group_stopped', None)
            if stopped:
                stopped(group, group_of)

    if extra.get('exclusive_control'):
        lease = Lease(gateway, types=frozenset(types), globs=parse_globs(extra.get('control_glob')),
                      takeover_role='admin' if auth else None, stations=stations,
                      on_lost=lambda session, group: safety.stop_session(session, in_group(group)),
                      stop_group=stop_group)
    d = Limits()
    limits = Limits(**{k: extra.get(k, getattr(d, k)) for k in
                       ('max_subscriptions', 'max_publishers', 'max_pending_calls', 'max_op_rate')})
    gateway.policy = SecurePolicy(settings, auth=auth, limits=limits, lease=lease, stations=stations, reads=reads,
                                  sessions=sessions)
    gateway.hooks.append(stations)

    if lease is not None:
        gateway.rules.append(lease.publish_hook)
        gateway.hooks.append(lease)
    gateway.rules.append(safety.publish_hook)
    gateway.hooks.append(safety)
    if timetable is not None:
        if lease is None:
            log.warning('--booking without --exclusive-control: slots seat their bookers and end on time, but '
                        'nothing keeps others\' commands off a booked robot')
        gateway.hooks.append(Slots(gateway, timetable, stations=stations, lease=lease, stop_group=stop_group,
                                   reset=extra.get('station_reset'), queue=queue))
    log.info('security: auth %s, exclusive control %s, stop on disconnect %s, cmd timeout %s s, '
             'cmd max age %s s%s', 'on' if auth else 'off', 'on' if lease else 'off', safety.stop_on_disconnect,
             safety.cmd_timeout, safety.cmd_max_age, ', stamps required' if safety.require_stamp else '')
