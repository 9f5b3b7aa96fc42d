"""The policy: what a client may see and do.

``Policy`` applies rosbridge's name globs and the Host and Origin checks; ``SecurePolicy`` adds
roles and the auth gate, per-client caps and op rate. ``gateway.policy`` is one of them.
"""

from __future__ import annotations

import asyncio
import re
from collections.abc import Callable
from dataclasses import dataclass
from fnmatch import fnmatchcase
from urllib.parse import urlsplit

from protocol import ops
from protocol.errors import ProtocolError

from .stations import person_of
from .names import (CONTROL_TOPIC, LOCAL_HOSTS, OWN_PREFIX, WRITING_ROSAPI, host_name, is_ip,  # noqa: F401 (re-exported)
                    own_names, parse_globs, parse_networks, refuse, target)
from ..auth.sessions import SESSION_COOKIE, Sessions
from ..settings import SecuritySettings
from .access import (GATEWAY_ROLE, NOT_AUTHENTICATED, PERMISSIONS, VERBS, Access, lowered,  # noqa: F401 (re-exported)
                     permission)
from ..auth.tokens import AuthError, Authenticator, Identity

_NAME = re.compile(r'[^A-Za-z0-9 _.@-]')
DEFAULT_PORTS = {'http': 80, 'https': 443, 'ws': 80, 'wss': 443}
SMALL_BODY = 64 * 1024   # bodies up to this size are read without a token (the login form)


def token_from_request(request) -> str | None:
    """A token given with a request: ?token= or Authorization: Bearer (the session cookie of
    /login is not a token: see ``sessions``)."""
    values = request.query_arguments.get('token')
    if values:
        return values[-1].decode('utf-8', 'replace')
    header = request.headers.get('Authorization', '')
    if header[:7].lower() == 'bearer ':
        return header[7:].strip()
    return None


def session_cookie(request) -> str | None:
    cookie = request.cookies.get(SESSION_COOKIE)
    return cookie.value if cookie is not None else None


def origin_parts(origin: str) -> tuple[str, str, int] | None:
    """(scheme, host, port) of an origin like http://127.0.0.1:9090 (the port filled in from
    the scheme); None for anything else (``null``, a path, a bad port)."""
    try:
        parts = urlsplit(origin.strip().lower())
        port = parts.port
    except ValueError:
        return None
    if parts.scheme not in DEFAULT_PORTS or not parts.hostname or parts.path not in ('', '/'):
        return None
    host = parts.hostname.rstrip('.')
    return parts.scheme, host, port if port is not None else DEFAULT_PORTS[parts.scheme]


class Policy:
    """The open gateway's rules (the name globs alone); ``SecurePolicy`` adds sign-in, limits,
    the driver lease and stations. Every reader asks ``policy.auth``, ``.sessions``, ``.lease``
    and ``.stations`` the same way: None where this gateway has none."""

    def __init__(self, settings, *, reads: Callable[[str], bool] = lambda name: False, keepers: tuple = (),
                 auth: Authenticator | None = None, stations=None):
        self.auth: Authenticator | None = auth
        self.sessions: Sessions | None = None
        self.lease = None       # rules.lease.Lease with --exclusive-control
        self.stations = stations   # rules.stations.Stations on a fleet
        self.allowed_origins = parse_globs(settings.allowed_origins)
        self.allowed_hosts = parse_globs(settings.allowed_hosts)
        self.trusted_proxies = parse_networks(settings.security.trusted_proxies)
        self.own_names = own_names()
        # who may do what to which name: rules.access (the role, the name globs, the keepers)
        self.access = Access({kind: parse_globs(getattr(settings, f'{kind}_glob'))
                              for kind in ('topics', 'topics_pub', 'topics_sub', 'services', 'params', 'actions')},
                             auth=auth is not None, stations=stations, reads=reads, keepers=keepers)

    @property
    def keepers(self) -> tuple:
        return self.access.keepers

    def admit(self, session, op) -> bool:
        """Called before every incoming op is handled: raise ProtocolError to refuse it with a
        status; return False to drop it silently (a client already being disconnected).
        Here every op that names a topic, service or action is checked, once."""
        wanted = target(op)
        if wanted is not None:
            try:
                self.check(session, *wanted, op.OP, op.id)
            except ProtocolError as e:
                refuse(op, e.message)
        return True

    def refusal(self, who, action: str, name: str | None) -> str | None:
        """The one access rule about names (``rules.access.Access``): None, or why ``who`` may not ``action`` ``name``."""
        return self.access.refusal(who, action, name)

    def check(self, session, action: str, name: str, op: str, id: str | None) -> None:
        """``access.decide(session, action, Name(name))``, asked for its words (``Access.refusal``,
        the decision's branch for names): every op with a name passes here, and building a ``Name``
        per op made this gate a quarter slower (measured: 2.1 -> 2.6 us of CPU per publish)."""
        why = self.access.refusal(session, action, name)
        if why is not None:
            raise ProtocolError(why, op=op, id=id)

    def visible(self, session, kind: str, name: str) -> bool:
        """For rosapi listings: kind is topics, services, actions or params."""
        return self.access.visible(kind, name)

    def authenticate(self, session, op) -> None:
        session.status('info', 'authentication is not required by this gateway', op.OP, op.id)

    def signed_in(self, session) -> bool:
        """Whether the client may make the gateway hold state for it (fragments): here always."""
        return True

    def host_allowed(self, host: str) -> bool:
        """The Host header of any request (DNS rebinding: a page on evil.example that resolves to
        this machine sends Host: evil.example). Passed: IP literals, this machine's names and
        *.localhost, mDNS names (*.local: resolved on the local network only), --allowed-hosts."""
        name = host_name(host)
        if name in self.own_names or is_ip(name) or name.endswith(('.localhost', '.local')):
            return True
        return self.allowed_hosts is not None and any(
            fnmatchcase(name, g.lower()) or fnmatchcase(host.lower(), g.lower()) for g in self.allowed_hosts)

    def body_refusal(self, request, size: int) -> tuple[int, str] | None:
        """(status, reason) to refuse an HTTP request body of this size (-1: chunked) by its
        headers, before it is read; None to read it."""
        return None

    def origin_allowed(self, origin: str, request) -> bool:
        """Browsers send Origin: the gateway's own origin passes (the scheme it was reached by, the
        host and port of its Host header; localhost, 127.0.0.1 and [::1] stand for each other on
        that same port), others only if an --allowed-origins glob lists them. A page on another
        port of the same machine is another origin (another program, perhaps anyone's)."""
        if self.allowed_origins is not None and any(fnmatchcase(origin, g) for g in self.allowed_origins):
            return True
        theirs = origin_parts(origin)
        if theirs is None:
            return False
        ours = origin_parts(f'{request.protocol}://{request.host or ""}')
        if ours is None or theirs[0] != ours[0] or theirs[2] != ours[2]:
            return False
        return theirs[1] == ours[1] or (theirs[1] in LOCAL_HOSTS and ours[1] in LOCAL_HOSTS)

    def connect_attrs(self, request) -> dict:
        """Per-connection facts (role, identity) known at the websocket upgrade."""
        return {}



@dataclass(frozen=True)
class Limits:
    max_subscriptions: int = SecuritySettings.max_subscriptions
    max_publishers: int = SecuritySettings.max_publishers
    max_pending_calls: int = SecuritySettings.max_pending_calls
    max_op_rate: float = SecuritySettings.max_op_rate     # ops per second per client; 0: unlimited


class SecurePolicy(Policy):
    def __init__(self, settings, *, auth: Authenticator | None = None, limits: Limits = Limits(), lease=None,
                 stations=None, reads: Callable[[str], bool] = lambda name: False, sessions: Sessions | None = None,
                 keepers: tuple = ()):
        super().__init__(settings, reads=reads, keepers=keepers, auth=auth, stations=stations)
        self.limits, self.lease = limits, lease
        self.sessions = sessions

    def identity_of(self, request) -> Identity | None:
        """Who sends a request: a token (?token=, Authorization: Bearer; the brake counts a
        wrong one against the client's address), else the session cookie (signed and looked up
        on the server: a forged or ended one is no one, and costs no guess). None: no one; raises
        AuthError for a wrong token or a brake that holds."""
        token = token_from_request(request)
        if token:
            return self.auth.token(request.remote_ip or '?', token)
        if self.sessions is not None:
            return self.sessions.find(session_cookie(request))
        return None

    # --- the gate in front of every op -------------------------------------------------------

    def signed_in(self, session) -> bool:
        return self.auth is None or 'role' in session.attrs

    def admit(self, session, op) -> bool:
        if not self._rate(session, op):
            return False
        if isinstance(op, (ops.Auth, ops.SetLevel)):
            return True
        if self.auth is not None and 'role' not in session.attrs:
            reason = session.attrs.get('auth_error')
            refuse(op, f'{NOT_AUTHENTICATED}{f" (the token given at connect: {reason})" if reason else ""}')
        wanted = target(op)
        if wanted is None:
            return True
        action, name = wanted
        try:
            wait = self.check(session, action, name, op.OP, op.id)
        except ProtocolError as e:
            refuse(op, e.message)
        self._caps(session, op, name)
        return wait or True   # a Wait (rules.settle): a call on a free lease of a fleet asks PostgreSQL first

    def _rate(self, session, op) -> bool:
        """A token bucket per client (burst: one second's worth, at least one op). Each op over
        the rate is refused with a status; a client still flooding after that many refusals in a
        row is closed (1008) once those statuses are sent, and its further ops are dropped."""
        rate = self.limits.max_op_rate
        if rate <= 0:
            return True
        burst = max(1.0, rate)
        now = asyncio.get_running_loop().time()
        tokens, last, refused = session.attrs.get('_rate', (burst, now, 0))
        tokens = min(burst, tokens + (now - last) * rate)
        if tokens >= 1:
            session.attrs['_rate'] = (tokens - 1, now, 0)
            return True
        refused += 1
        session.attrs['_rate'] = (tokens, now, refused)
        threshold = max(100, int(rate))
        if refused > threshold:
            if refused == threshold + 1:
                asyncio.ensure_future(session.hang_up(1008, 'op rate limit exceeded'))
            return False
        refuse(op, f'op rate limit of {rate:g} per second exceeded; slow down')

    def _caps(self, session, op, name: str) -> None:
        lim = self.limits
        if isinstance(op, ops.Subscribe):
            if name not in session.subscriptions and len(session.subscriptions) >= lim.max_subscriptions:
                refuse(op, f'{name}: this client already has {lim.max_subscriptions} subscriptions '
                                     '(--max-subscriptions)')
        elif isinstance(op, (ops.Publish, ops.Advertise)):
            if name not in session.publishers and len(session.publishers) >= lim.max_publishers:
                refuse(op, f'{name}: this client already advertises {lim.max_publishers} topics '
                                     '(--max-publishers)')
        elif isinstance(op, (ops.CallService, ops.SendActionGoal)):
            if len(session.tasks) >= lim.max_pending_calls:
                refuse(op, f'{name}: this client already has {lim.max_pending_calls} calls and goals '
                                     'pending (--max-pending-calls)')

    # --- Policy hooks ------------------------------------------------------------------------

    def check(self, session, action: str, name: str, op: str, id: str | None):
        """Raises ProtocolError to refuse; returns a ``rules.settle.Wait`` when the op must wait for
        the driver lease (a call or goal under --control-glob on a free lease of a fleet)."""
        super().check(session, action, name, op, id)
        if self.lease is not None and action in ('call', 'send_goal'):
            return self.lease.require(session, name)
        return None

    def authenticate(self, session, op) -> None:
        if self.auth is None:
            super().authenticate(session, op)
            return
        remote = session.remote or '?'
        try:
            if op.token is not None:
                identity = self.auth.token(remote, op.token)
            elif op.mac is not None:
                identity = self.auth.rosauth(remote, op)
            else:
                raise ProtocolError('give a token (or the rosauth fields mac, client, dest, rand, t, level, end)',
                                    op=op.OP, id=op.id)
        except AuthError as e:
            raise ProtocolError(str(e), op=op.OP, id=op.id) from None
        session.attrs.update(role=identity.role, name=identity.name, person=person_of(identity, {}))
        session.attrs.pop('auth_error', None)
        session.status('info', f'authenticated as {identity.name} ({identity.role})', op.OP, op.id)

    def body_refusal(self, request, size: int) -> tuple[int, str] | None:
        """With auth on, only small bodies (the login form) come without a valid token."""
        if self.auth is None or 0 <= size <= SMALL_BODY:
            return None
        try:
            identity = self.identity_of(request)
        except AuthError as e:
            return e.status, str(e)
        if identity is None:
            return 401, 'a token is required to send this: sign in at /login or send Authorization: Bearer'
        return None

    def connect_attrs(self, request) -> dict:
        attrs: dict = {}
        label = request.query_arguments.get('name')
        if label:
            attrs['name'] = _NAME.sub('', label[-1].decode('utf-8', 'replace'))[:32]
        if self.auth is None:
            key = person_of(None, request.cookies)   # the browser's id: its station stays its own
            if key is not None:
                attrs['person'] = key
            return attrs
        try:
            identity = self.identity_of(request)
        except AuthError as e:
            attrs['auth_error'] = str(e)
        else:
            if identity is not None:
                attrs.update(role=lowered(identity.role, request.query_arguments.get('as')),
                             name=identity.name, person=person_of(identity, {}))
                if self.sessions is not None and not token_from_request(request):   # closed when it ends
                    attrs['signin'] = self.sessions.key_of(session_cookie(request))
        return attrs


