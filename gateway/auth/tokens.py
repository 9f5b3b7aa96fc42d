"""Tokens and roles from a TOML file, rosauth MACs, and a brake on guessing.

    [[tokens]]
    name = "teacher"
    role = "admin"                 # viewer, operator or admin
    token = "a long random string" # or: sha256 = "<hex digest of the token>"

    [rosauth]                      # optional: the ROS 1 era ``auth`` op (mac, client, dest, rand, t, level, end)
    secret = "shared secret"
    role = "operator"              # when ``level`` names no role
    allowed_time_delta = 5.0
"""

from __future__ import annotations

import hashlib
import hmac
import re
import time
import tomllib
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path


class Role(StrEnum):
    """The roles a token, an LMS launch or rosauth gives, lowest first (``Role(value)`` parses one)."""
    VIEWER = 'viewer'
    OPERATOR = 'operator'
    ADMIN = 'admin'


ROLES = tuple(r.value for r in Role)
TOKEN_CHARS = re.compile(r'[A-Za-z0-9._~-]{8,}')


@dataclass(frozen=True)
class Identity:
    """Who a client is. ``name``: what pages show; ``key``: what the person owns things under
    (station, library space, runs, recordings) when the name alone is not unique: an LMS launch's
    issuer and subject (``lti-`` and a digest), stable across launches and courses of that platform."""
    name: str
    role: str
    key: str = ''

    @property
    def owner(self) -> str:
        return self.key or self.name

    def listed(self, entries) -> bool:
        """Whether a token file's entries still hold this name with this role."""
        return any(i.name == self.name and i.role == self.role for _, i in entries)


class AuthError(Exception):
    """A refused attempt; the message is safe to show the client. ``status``: its HTTP status."""
    status = 401


class TooManyAttempts(AuthError):
    """The brake holds: too many failed attempts from one address."""
    status = 429


def _digest(token: str) -> bytes:
    return hashlib.sha256(token.encode('utf-8')).digest()


def _role(value, where: str) -> str:
    role = role_named(value)
    if role is None:
        raise ValueError(f'{where}: role must be one of {", ".join(ROLES)}, not {value!r}')
    return role


def role_named(value) -> str | None:
    """``value`` as a role's word, or None when it names none (parsed by ``Role``)."""
    try:
        return Role(value).value
    except ValueError:
        return None


@dataclass(frozen=True)
class RosAuth:
    secret: str
    role: str = 'operator'
    allowed_time_delta: float = 5.0

    def mac(self, client: str, dest: str, rand: str, t: int, level: str, end: int) -> str:
        """rosauth: sha512 over secret, client, dest, rand, t.sec, level, end.sec (hex)."""
        text = f'{self.secret}{client}{dest}{rand}{t}{level}{end}'
        return hashlib.sha512(text.encode('utf-8')).hexdigest()


def _seconds(value) -> int | None:
    """ROS 1 times come as {secs, nsecs}, ROS 2 as {sec, nanosec}, or as a number."""
    if isinstance(value, dict):
        value = value.get('secs', value.get('sec'))
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return int(value)


class TokenStore:
    def __init__(self, entries: list[tuple[bytes, Identity]], rosauth: RosAuth | None = None):
        self.entries = entries
        self.rosauth = rosauth
        self._used_macs: dict[str, float] = {}

    @classmethod
    def load(cls, path: str | Path) -> TokenStore:
        with open(path, 'rb') as f:
            data = tomllib.load(f)
        entries = []
        for i, item in enumerate(data.get('tokens', [])):
            where = f'{path}: tokens[{i}]'
            if not isinstance(item, dict):
                raise ValueError(f'{where}: expected a table')
            role = _role(item.get('role'), where)
            name = str(item.get('name') or f'{role}{i + 1}')
            if 'token' in item:
                token = str(item['token'])
                if not TOKEN_CHARS.fullmatch(token):
                    raise ValueError(f'{where}: a token is 8 or more of A-Z a-z 0-9 . _ ~ - '
                                     '(safe in URLs and cookies), e.g. from secrets.token_urlsafe()')
                digest = _digest(token)
            elif 'sha256' in item:
                try:
                    digest = bytes.fromhex(str(item['sha256']))
                except ValueError:
                    digest = b''
                if len(digest) != 32:
                    raise ValueError(f'{where}: sha256 must be 64 hex digits')
            else:
                raise ValueError(f'{where}: give token or sha256')
            entries.append((digest, Identity(name, role)))
        rosauth = None
        if 'rosauth' in data:
            section = data['rosauth']
            if not section.get('secret'):
                raise ValueError(f'{path}: [rosauth] needs a secret')
            rosauth = RosAuth(str(section['secret']), _role(section.get('role', 'operator'), f'{path}: [rosauth]'),
                              float(section.get('allowed_time_delta', 5.0)))
        if not entries and rosauth is None:
            raise ValueError(f'{path}: no [[tokens]] and no [rosauth]: nobody could connect')
        return cls(entries, rosauth)

    def check_token(self, token: str) -> Identity | None:
        """Constant time in the token: every entry is compared, digests of equal length."""
        digest = _digest(token)
        found = None
        for stored, identity in self.entries:
            if hmac.compare_digest(stored, digest) and found is None:
                found = identity
        return found

    def check_rosauth(self, mac, client, dest, rand, t, level, end, now: float | None = None) -> Identity | None:
        ra = self.rosauth
        if ra is None or not isinstance(mac, str):
            return None
        t_sec, end_sec = _seconds(t), _seconds(end)
        if t_sec is None or end_sec is None:
            return None
        now = time.time() if now is None else now
        expected = ra.mac(client or '', dest or '', rand or '', t_sec, level or '', end_sec)
        if not hmac.compare_digest(expected.encode(), mac.encode('utf-8', 'replace')):
            return None
        if abs(now - t_sec) > ra.allowed_time_delta or end_sec < now:
            return None
        self._used_macs = {m: exp for m, exp in self._used_macs.items() if exp > now}
        if mac in self._used_macs:   # a replayed MAC
            return None
        self._used_macs[mac] = now + 2 * ra.allowed_time_delta
        role = role_named(level) or ra.role
        return Identity(client or 'rosauth', role)


class Brake:
    """Failed attempts per remote address: the first few are free, then each must wait twice as
    long as the one before (from ``base`` up to ``cap`` seconds). Attempts inside the wait are
    refused unchecked, so guessing faster gains nothing. Success does not reset the count (a valid
    low-role token must not buy more guesses); an address is forgotten after ``forget`` s quiet."""

    def __init__(self, free: int = 3, base: float = 0.5, cap: float = 30.0, forget: float = 900.0,
                 max_entries: int = 10000, clock: Callable[[], float] = time.monotonic):
        self.free, self.base, self.cap, self.forget = free, base, cap, forget
        self.max_entries, self.clock = max_entries, clock
        self._failures: OrderedDict[str, tuple[int, float]] = OrderedDict()

    def retry_after(self, key: str) -> float:
        entry = self._failures.get(key)
        if entry is None:
            return 0.0
        count, last = entry
        now = self.clock()
        if now - last > self.forget:
            del self._failures[key]
            return 0.0
        if count < self.free:
            return 0.0
        wait = min(self.cap, self.base * 2 ** (count - self.free))
        return max(0.0, last + wait - now)

    def failed(self, key: str) -> None:
        count, _ = self._failures.pop(key, (0, 0.0))
        self._failures[key] = (count + 1, self.clock())
        while len(self._failures) > self.max_entries:
            self._failures.popitem(last=False)


class Authenticator:
    """Every attempt goes through here: the brake first, then the check."""

    def __init__(self, store: TokenStore, brake: Brake | None = None):
        self.store = store
        self.brake = brake or Brake()

    def _attempt(self, remote: str, check: Callable[[], Identity | None], what: str) -> Identity:
        wait = self.brake.retry_after(remote)
        if wait > 0:
            raise TooManyAttempts(f'too many failed attempts from {remote}; retry in {wait:.1f} s')
        identity = check()
        if identity is None:
            self.brake.failed(remote)
            raise AuthError(f'invalid {what}')
        return identity

    def token(self, remote: str, token: str) -> Identity:
        return self._attempt(remote, lambda: self.store.check_token(token), 'token')

    def rosauth(self, remote: str, op) -> Identity:
        if self.store.rosauth is None:
            raise AuthError('rosauth MACs are not accepted by this gateway; send a token')
        return self._attempt(remote, lambda: self.store.check_rosauth(
            op.mac, op.client, op.dest, op.rand, op.t, op.level, op.end), 'rosauth MAC')
