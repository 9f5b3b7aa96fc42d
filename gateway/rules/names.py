"""Names: rosbridge's name globs (topics, services, params, actions), the names this machine
goes by (for Host and Origin checks), and which name an incoming op asks for."""

from __future__ import annotations

import ipaddress
import socket
from fnmatch import fnmatchcase
from urllib.parse import urlsplit

from typing import NoReturn

from protocol import ops
from protocol.errors import ProtocolError

OWN_PREFIX = '/rosgate/'              # the gateway's own topics (driver, runs' state and output)
CONTROL_TOPIC = '/rosgate/control'    # where clients ask for the driver lease
WRITING_ROSAPI = ('/rosapi/set_param', '/rosapi/delete_param')

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


HIDDEN_ACTION = '/_action/'    # an action's own services and topics: NAME/_action/send_goal, .../feedback


def action_of(name: str) -> str | None:
    """The action whose hidden service or topic ``name`` is (``/fib/_action/send_goal`` -> ``/fib``), else None."""
    base, found, _ = name.partition(HIDDEN_ACTION)
    return base if found and base else None


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


def parse_networks(value: str | None) -> tuple:
    """--trusted-proxies: addresses or networks, comma or space separated ("127.0.0.1, 10.0.0.0/8")."""
    out = []
    for item in (parse_globs(value) or ()):
        try:
            out.append(ipaddress.ip_network(item, strict=False))
        except ValueError:
            raise ValueError(f'{item!r} is not an address or a network (e.g. 127.0.0.1 or 10.0.0.0/8)') from None
    return tuple(out)


def in_networks(address: str, networks) -> bool:
    try:
        ip = ipaddress.ip_address(address.split('%', 1)[0])
    except ValueError:
        return False
    if ip.version == 6 and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return any(ip in n for n in networks)


def forwarded(request, proxies) -> None:
    """Behind a TLS reverse proxy: when the request comes from one of ``proxies``, believe its
    X-Forwarded-Proto, X-Forwarded-Host and X-Forwarded-For (the client: the rightmost address
    that is not itself a trusted proxy), so origins, redirects, Secure cookies, the sign-in brake
    and the logs see what the browser sees. From anyone else these headers change nothing (a
    client could claim any address and dodge the brake)."""
    if not proxies or not in_networks(request.remote_ip or '', proxies):
        return
    headers = request.headers
    client = request.remote_ip
    for address in reversed([a.strip() for a in headers.get('X-Forwarded-For', '').split(',') if a.strip()]):
        if not is_ip(address):
            break
        client = address
        if not in_networks(address, proxies):
            break
    request.remote_ip = client
    proto = headers.get('X-Forwarded-Proto', '').split(',')[0].strip().lower()
    if proto in ('http', 'https'):
        request.protocol = proto
    host = headers.get('X-Forwarded-Host', '').split(',')[0].strip()
    if host:
        request.host = host
        request.host_name = host_name(host)


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


class Refused(ProtocolError):
    """An op refused by the rules in front of it (the policy's gate): the status names op and id;
    the session's catch site (``bridge.session``) also answers a refused call or goal with its
    failed reply, so clients waiting on it (roslibjs, roslibpy) fail at once instead of timing out."""


def refuse(op, message: str) -> NoReturn:
    """Refuse ``op``: the rules write nothing into the session, they raise."""
    raise Refused(message, op=op.OP, id=op.id)
