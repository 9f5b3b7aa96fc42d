"""Sign-in sessions: what a browser's cookie stands for, kept on the server.

The cookie ``rosgate_session`` holds a random session id, signed with tornado's signed values
(HMAC-SHA256, a timestamp inside) under a secret kept in the data directory
(``$XDG_DATA_HOME/rosgate/cookie_secret``, mode 0600, made at first start) — never the token, so a
copied cookie is not a lasting credential. Each session is a row of the store's ``sessions``
table (the id's SHA-256, who: name, role, owner key, how they signed in, and when it ends), so it
survives a restart and is ended on the server: signing out deletes the row, and the cookie is
then worth nothing anywhere; every session ends at its expiry (``--session-hours``); a token
session whose name and role the tokens file no longer lists is dropped at start-up.

Everyone who signed in is also kept in ``people`` (owner key, name, role, how, last seen), after
their sessions end: a teacher books a slot "for" a student who launched from the LMS by her name
(``Sessions.people``), though her key is a digest she never typed.

Lookups run on every request and websocket upgrade, on the event loop: the live sessions are held
in memory (loaded once at start-up, written through to the store on its own thread), so no
lookup waits on a disk. With several gateways on one PostgreSQL (a fleet, ``store.fleet``), each
tells the others of a sign-in (NOTIFY, and they read new sessions every second): a cookie from
gateway A works on B behind a proxy that is not sticky. A sign-out is a row (``revoked``): A
answers once it is committed and every live gateway has applied it (or lapsed, ``Fleet.everywhere``),
so a request on B after A answered is refused; that session's websockets close on every gateway as
it applies the row. A gateway that cannot confirm the shared state refuses sign-ins (503) until it
can: it may not have heard of a logout elsewhere, and the gateway that answered it counted on that.
"""

from __future__ import annotations

import asyncio
import hashlib
import logging
import os
import secrets
import time
from dataclasses import dataclass
from typing import Protocol

import sqlalchemy as sa
import tornado.web

from ..settings import SecuritySettings, data_dir
from ..store import METADATA
from .tokens import AuthError, Identity

log = logging.getLogger('rosgate.sessions')
SESSION_COOKIE = 'rosgate_session'
DEFAULT_HOURS = SecuritySettings.session_hours
COMMIT_WAIT = 15.0      # s a sign-out waits for the database to take it before answering without it


class Unconfirmed(AuthError):
    """A sign-in this gateway cannot confirm now (a fleet's database away): try again shortly."""
    status = 503


def _who() -> list[sa.Column]:
    """The columns that say who: the name shown, the role, how they signed in (token or lti)."""
    return [sa.Column('name', sa.String(200), nullable=False),
            sa.Column('role', sa.String(16), nullable=False),
            sa.Column('kind', sa.String(16), nullable=False)]


TABLE = sa.Table(
    'sessions', METADATA,
    sa.Column('id_hash', sa.String(64), primary_key=True),
    *_who(),
    sa.Column('owner', sa.String(100), nullable=False),
    sa.Column('created', sa.Float, nullable=False),
    sa.Column('expires', sa.Float, nullable=False),
)

PEOPLE = sa.Table(
    'people', METADATA,
    sa.Column('owner', sa.String(100), primary_key=True),
    *_who(),
    sa.Column('seen', sa.Float, nullable=False),
)


@dataclass(frozen=True)
class Person:
    owner: str
    name: str
    role: str
    kind: str
    seen: float

    def json(self) -> dict:
        return {'id': self.owner, 'name': self.name, 'role': self.role, 'kind': self.kind, 'seen': self.seen}


def cookie_secret(path=None) -> bytes:
    """The secret that signs session cookies: read from the data directory, made there once."""
    path = path or data_dir('cookie_secret')
    try:
        with open(path, 'rb') as f:
            value = f.read().strip()
        if len(value) >= 32:
            return value
    except FileNotFoundError:
        pass
    path.parent.mkdir(parents=True, exist_ok=True)
    value = secrets.token_urlsafe(48).encode()
    fd = os.open(f'{path}.tmp', os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, 'wb') as f:
        f.write(value)
    os.replace(f'{path}.tmp', path)
    return value


def _hash(session_id: str) -> str:
    return hashlib.sha256(session_id.encode()).hexdigest()


class SignOutEvents(Protocol):
    """Where a sign-in's end is told (``rules.hooks.Hooks``: ``on_signed_out`` of every part)."""
    def signed_out(self, key: str) -> None: ...


@dataclass(frozen=True)
class Session:
    identity: Identity
    kind: str
    expires: float


class Sessions:
    """Begin, find and end sessions. ``store``: the gateway's Store (None: kept in memory only)."""

    def __init__(self, store, secret: bytes, *, hours: float = DEFAULT_HOURS, still_valid=lambda s: True,
                 fleet=None, events: SignOutEvents | None = None):
        """fleet: store.fleet.Fleet (the other gateways hear sign-ins and outs; rules.fleet); events:
        told of each sign-in ended (``rules.hooks.Hooks``: its websockets close, bridge.doors)."""
        self.store, self.secret, self.seconds = store, secret, hours * 3600
        self.live: dict[str, Session] = {}
        self.known: dict[str, Person] = {}
        self.fleet, self.events = fleet, events
        if store is not None:
            now = time.time()
            self.known = {r.owner: Person(r.owner, r.name, r.role, r.kind, r.seen)
                          for r in store.run_now(lambda c: c.execute(sa.select(PEOPLE)).all())}
            rows = store.run_now(lambda c: c.execute(sa.select(TABLE)).all())
            gone = []
            for row in rows:
                s = Session(Identity(row.name, row.role, row.owner), row.kind, row.expires)
                if row.expires > now and still_valid(s):
                    self.live[row.id_hash] = s
                else:
                    gone.append(row.id_hash)
            if gone:
                store.run_now(lambda c: c.execute(TABLE.delete().where(TABLE.c.id_hash.in_(gone))))
            log.info('sessions: %d signed in, %d ended or expired', len(self.live), len(gone))

    @property
    def max_age_days(self) -> float:
        return self.seconds / 86400

    def begin(self, identity: Identity, kind: str) -> str:
        """A new session for ``identity``; returns the signed cookie value."""
        session_id = secrets.token_urlsafe(32)
        now = time.time()
        s = Session(identity, kind, now + self.seconds)
        key = _hash(session_id)
        self.live[key] = s
        if self.store is not None:
            row = dict(id_hash=key, name=identity.name[:200], role=identity.role, owner=identity.owner[:100],
                       kind=kind, created=now, expires=s.expires)
            insert = lambda c: c.execute(TABLE.insert().values(**row))   # noqa: E731
            if self.fleet is not None:   # in order with a sign-out's revocation, on the fleet's thread
                self.fleet.write(insert)
                self.fleet.notify('login', **row)
            else:
                self.store.submit(insert)
        self._seen(Person(identity.owner[:100], identity.name[:200], identity.role, kind, now))
        return tornado.web.create_signed_value(self.secret, SESSION_COOKIE, session_id).decode()

    def _key(self, cookie_value: str | None) -> str | None:
        if not cookie_value:
            return None
        raw = tornado.web.decode_signed_value(self.secret, SESSION_COOKIE, cookie_value,
                                              max_age_days=self.max_age_days)
        return _hash(raw.decode('utf-8', 'replace')) if raw else None

    def key_of(self, cookie_value: str | None) -> str | None:
        """The session a cookie names (its id's hash), signed and not ended: what its websockets keep."""
        key = self._key(cookie_value)
        return key if key in self.live else None

    def find(self, cookie_value: str | None) -> Identity | None:
        """Who a cookie stands for, or None (no cookie, a bad signature, ended or expired); in a
        fleet that cannot confirm the shared state now, Unconfirmed (a logout elsewhere may be unknown)."""
        key = self._key(cookie_value)
        s = self.live.get(key) if key else None
        if s is None:
            return None
        if s.expires <= time.time():
            self._drop(key)
            return None
        if self.fleet is not None and not self.fleet.confirmed():
            raise Unconfirmed(f'{self.fleet.why_unconfirmed()}, so it cannot confirm your sign-in now; try again '
                              'in a moment')
        return s.identity

    def end(self, cookie_value: str | None) -> bool:
        """Sign out here (alone, or not waiting for the others): True when there was a session."""
        key = self._key(cookie_value)
        if key is None or key not in self.live:
            return False
        self._drop(key)
        self._revoked(key)
        return True

    async def sign_out(self, cookie_value: str | None) -> str | None:
        """Sign out everywhere before answering: the session ended here at once, its row deleted
        and, in a fleet, a ``revoked`` row committed and applied by every live gateway. None when
        done; else why not (the database did not answer: the others learn it when it does)."""
        key = self._key(cookie_value)
        if key is None:
            return None
        s = self.live.pop(key, None)
        self._revoked(key)
        if self.store is None:
            return None
        delete = lambda c: c.execute(TABLE.delete().where(TABLE.c.id_hash == key))   # noqa: E731
        if self.fleet is None:
            await self.store.run(delete)
            return None
        until = s.expires if s is not None else time.time() + self.seconds
        committed = self.fleet.put('revoked', key, {'until': until}, until=until, also=delete,
                                   after=self.fleet.db.gateways)
        try:
            done = await asyncio.wait_for(asyncio.shield(committed), COMMIT_WAIT)
        except Exception as e:
            log.warning('sign-out not committed within %g s (%s): the other gateways learn it when the database '
                        'answers', COMMIT_WAIT, str(e) or type(e).__name__)
            return ('you are signed out on this gateway; the database did not answer, so the other gateways '
                    'learn it when it does')
        late = await self.fleet.everywhere(done, 'revoked', key)
        if late:
            log.warning('sign-out: gateways %s neither applied it nor lapsed', ', '.join(late))
        return None

    def _seen(self, person: Person) -> None:
        self.known[person.owner] = person
        if self.store is not None:
            def write(c):
                c.execute(PEOPLE.delete().where(PEOPLE.c.owner == person.owner))
                c.execute(PEOPLE.insert().values(owner=person.owner, name=person.name, role=person.role,
                                                 kind=person.kind, seen=person.seen))
            self.store.submit(write)

    def people(self, who: str | None = None) -> list[Person]:
        """Everyone who ever signed in here, newest first; ``who``: only those it names (their
        id, or their name in any case)."""
        found = sorted(self.known.values(), key=lambda p: -p.seen)
        if who is None:
            return found
        return [p for p in found if p.owner == who or p.name.casefold() == who.casefold()]

    def heard_login(self, row: dict) -> None:
        """A sign-in on another gateway of the fleet."""
        self.live[row['id_hash']] = Session(Identity(row['name'], row['role'], row['owner']), row['kind'],
                                            row['expires'])

    def revoked_elsewhere(self, key: str) -> None:
        """A sign-out through another gateway (its row): refused here from now, its websockets
        closed, and that gateway told (it answers once every gateway has said so)."""
        self.live.pop(key, None)
        self._revoked(key)
        self.fleet.ack('revoked', key)

    def created_since(self, c: sa.Connection, since: float) -> list:
        """The sessions begun since (on the fleet's thread, each second): a sign-in not heard."""
        return c.execute(sa.select(TABLE).where(TABLE.c.created > since)).all()

    def heard_created(self, rows) -> None:
        now = time.time()
        for row in rows:
            if row.id_hash not in self.live and row.expires > now and ('revoked', row.id_hash) not in self.fleet.values:
                self.heard_login(row._asdict())

    def _revoked(self, key: str) -> None:
        if self.events is not None:
            self.events.signed_out(key)

    def _drop(self, key: str) -> None:
        self.live.pop(key, None)
        if self.store is not None:
            self.store.submit(lambda c: c.execute(TABLE.delete().where(TABLE.c.id_hash == key)))
