"""What a client may see and do: rosbridge's name globs (topics, services, params, actions)."""

from __future__ import annotations

import ipaddress
import socket
from fnmatch import fnmatchcase
from urllib.parse import urlsplit

from typing import NoReturn

from protocol import ops
from protocol.errors import ProtocolError

# what each checked action needs: (glob kinds that must all match)
ACTION_KINDS = {
    'publish': ('topics', 'topics_pub'),
    'subscribe': ('topics', 'topics_sub'),
    'call': ('services',),
    'advertise_service': ('services',),
    'send_goal': ('actions',),
    'advertise_action': ('actions',),
    'param': ('params',),
}


def parse_globs(value: str | None) -> tuple[str, ...] | None:
    """rosbridge style: "['/turtle1/*', '/rosout']" or a plain comma/space separated list."""
    if value is None:
        return None
    text = value.strip().strip('[]')
    items = [item.strip().strip('\'"') for item in text.replace(',', ' ').split()]
    items = [item for item in items if item]
    return tuple(items) if items else None


LOCAL_HOSTS = frozenset({'localhost', '127.0.0.1', '::1', '[::1]'})


def host_name(host: str) -> str:
    """The name in a Host header: no port, no brackets, no trailing dot, lower case."""
    host = host.strip().lower()
    if host.startswith('['):
        host = host[1:].split(']', 1)[0]
    elif host.count(':') == 1:
        host = host.split(':', 1)[0]
    return host.rstrip('.')


def own_names() -> frozenset[str]:
    """This machine's names: localhost and its host name, bare and as an mDNS .local name."""
    names = {'localhost'}
    full = socket.gethostname().lower().rstrip('.')
    if full:
        short = full.split('.', 1)[0]
        names |= {full, short, f'{short}.local'}
    return frozenset(names)


def is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name.split('%', 1)[0])
    except ValueError:
        return False
    return True


class Policy:
    def __init__(self, settings):
        self.allowed_origins = parse_globs(settings.allowed_origins)
        self.allowed_hosts = parse_globs(settings.allowed_hosts)
        self.own_names = own_names()
        self.globs = {
            kind: parse_globs(getattr(settings, f'{kind}_glob'))
            for kind in ('topics', 'topics_pub', 'topics_sub', 'services', 'params', 'actions')
        }

    def matches(self, kind: str, name: str) -> bool:
        globs = self.globs.get(kind)
        return globs is None or any(fnmatchcase(name, g) for g in globs)

    def allows(self, session, action: str, name: str) -> bool:
        return all(self.matches(kind, name) for kind in ACTION_KINDS[action])

    def admit(self, session, op) -> bool:
        """Called before every incoming op is handled: raise ProtocolError to refuse it with a
        status; return False to drop it silently (a client already being disconnected).
        Here every op that names a topic, service or action is checked, once."""
        wanted = target(op)
        if wanted is not None:
            try:
                self.check(session, *wanted, op.OP, op.id)
            except ProtocolError as e:
                refuse(session, op, e.message)
        return True

    def check(self, session, action: str, name: str, op: str, id: str | None) -> None:
        if not self.allows(session, action, name):
            raise ProtocolError(f'{name} is not allowed for {action} by this gateway', op=op, id=id)

    def visible(self, session, kind: str, name: str) -> bool:
        """For rosapi listings: kind is topics, services, actions or params."""
        if kind == 'topics':
            return self.matches('topics', name) and (
                self.matches('topics_pub', name) or self.matches('topics_sub', name))
        return self.matches(kind, name)

    def authenticate(self, session, op) -> None:
        session.status('info', 'authentication is not required by this gateway', op.OP, op.id)

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
        """Browsers send Origin: the gateway's own origin and localhost pass, others only if listed."""
        if self.allowed_origins is not None and any(fnmatchcase(origin, g) for g in self.allowed_origins):
            return True
        host = urlsplit(origin).hostname or ''
        own = (request.host or '').rsplit(':', 1)[0].strip('[]')
        return host == own or host in LOCAL_HOSTS

    def connect_attrs(self, request) -> dict:
        """Per-connection facts (role, identity) known at the websocket upgrade."""
        return {}

    def http_routes(self) -> list:
        return []


def _absolute(name: str) -> str:
    return name if name.startswith('/') else '/' + name


def target(op) -> tuple[str, str] | None:
    """(action, name) that an incoming op asks for, or None for ops that need no check."""
    if isinstance(op, ops.Subscribe):
        return 'subscribe', _absolute(op.topic)
    if isinstance(op, (ops.Publish, ops.Advertise)):
        return 'publish', _absolute(op.topic)
    if isinstance(op, ops.CallService):
        return 'call', _absolute(op.service)
    if isinstance(op, ops.SendActionGoal):
        return 'send_goal', _absolute(op.action)
    if isinstance(op, ops.AdvertiseService):
        return 'advertise_service', _absolute(op.service)
    if isinstance(op, ops.AdvertiseAction):
        return 'advertise_action', _absolute(op.action)
    return None


def refuse(session, op, message: str) -> NoReturn:
    """A status error naming op and id; calls and goals also get their failed reply so clients
    waiting on them (roslibjs, roslibpy) fail at once instead of timing out."""
    if isinstance(op, ops.CallService):
        session.reply({'op': 'service_response', 'service': op.service, 'id': op.id,
                       'values': message, 'result': False})
    elif isinstance(op, ops.SendActionGoal):
        session.reply({'op': 'action_result', 'action': op.action, 'id': op.id,
                       'values': message, 'status': 0, 'result': False})
    raise ProtocolError(message, op=op.OP, id=op.id)
