"""What a client may see and do: rosbridge's name globs (topics, services, params, actions)."""

from __future__ import annotations

from fnmatch import fnmatchcase
from urllib.parse import urlsplit

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


class Policy:
    def __init__(self, settings):
        self.allowed_origins = parse_globs(settings.allowed_origins)
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
        status; return False to drop it silently (a client already being disconnected)."""
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
