"""Grades back to the LMS (LTI Advantage, Assignment and Grade Services): one score per attempt.

A launch whose id_token carries the AGS endpoint claim is remembered (``remember_launch``): the
line item URL per (person, resource link), with the platform that issued it and the exercise the
link opens (``exercise_of``: its custom ``exercise``, which the deep link put there, or ``?exercise=``
in its target link; a platform that kept neither: the line item's ``resourceId``, read from the
platform by ``resolve``, beside the launch and again when a result finds no link). ``Outbox.on_attempt_ended`` is
the exercises' checker's event (``rules.hooks``): when an attempt ends, passed or failed, its score (0..1,
a failed attempt's partial score too) is queued for the newest launch of that person from a link
of that exercise, and nothing is queued for someone who did not launch from one. ``post_result``
is the one door to a score; only the gateway's checker calls it, no page or rosbridge op reaches
it, so no browser request can post, forge or replay a score. The outbox is keyed by the attempt
id: a second call for the same attempt is a no-op, so the LMS's gradebook gets one score per attempt.

``Outbox.flush`` posts what is due with the tool's own client-credentials token (RFC 7523: a JWT
assertion signed with the tool's key by PyJWT, POSTed to the platform's token endpoint); a failure
(the LMS down, a 5xx) leaves the row and sets its next try with exponential backoff (10 s doubling
to an hour), so a score reaches the LMS when it comes back, also across gateway restarts. One
flush runs at a time (a lock): a result's own flush and the timer's never post a row twice; and
a row is claimed in the store before it is posted (a conditional update), so the gateways of a
fleet sharing one database do not post it twice either.
"""

from __future__ import annotations

import asyncio
import json
import logging
import secrets
import time
import urllib.parse
from datetime import datetime, timezone

import jwt
import sqlalchemy as sa
from tornado.httpclient import AsyncHTTPClient, HTTPClientError, HTTPRequest
from tornado.ioloop import PeriodicCallback

from ..rules.hooks import Hook
from ..store import METADATA, Store
from ..auth.lti import CLAIM, LtiConfig, Registration

log = logging.getLogger('rosgate.grades')
AGS_CLAIM = 'https://purl.imsglobal.org/spec/lti-ags/claim/endpoint'
SCOPE_SCORE = 'https://purl.imsglobal.org/spec/lti-ags/scope/score'
SCOPE_LINEITEM = 'https://purl.imsglobal.org/spec/lti-ags/scope/lineitem'
SCOPE_LINEITEM_READ = SCOPE_LINEITEM + '.readonly'
LINEITEM = 'application/vnd.ims.lis.v2.lineitem+json'
BACKOFF_FIRST, BACKOFF_MAX = 10.0, 3600.0
HOLD = 120.0   # s a gateway holds a score it is posting (the gateways of a fleet share the outbox)

LINKS = sa.Table(
    'ags_links', METADATA,
    sa.Column('person', sa.String(64), primary_key=True),
    sa.Column('resource_link', sa.String(255), primary_key=True),
    sa.Column('issuer', sa.String(255), nullable=False),
    sa.Column('client_id', sa.String(255), nullable=False),
    sa.Column('subject', sa.String(255), nullable=False),   # the LMS's userId for the score
    sa.Column('lineitem', sa.String(1000), nullable=False),
    sa.Column('exercise', sa.String(100), nullable=True),   # the exercise the link opens (exercise_of)
    sa.Column('scopes', sa.String(1000), nullable=False, default=''),   # the AGS scopes the launch offered
    sa.Column('launched', sa.Float, nullable=False, default=0.0),
)
OUTBOX = sa.Table(
    'ags_outbox', METADATA,
    sa.Column('attempt_id', sa.String(128), primary_key=True),   # one score per attempt, ever
    sa.Column('person', sa.String(64), nullable=False),
    sa.Column('resource_link', sa.String(255), nullable=False),
    sa.Column('score', sa.Float, nullable=False),
    sa.Column('comment', sa.String(200), nullable=True),     # passed or failed, and why it ended
    sa.Column('created', sa.Float, nullable=False),
    sa.Column('tries', sa.Integer, nullable=False, default=0),
    sa.Column('next_try', sa.Float, nullable=False),
    sa.Column('posted', sa.Float, nullable=True),
    sa.Column('last_error', sa.String(500), nullable=True),
)


class GradeError(Exception):
    """A score that may not be posted (no launch from that line item, a score out of range)."""


def exercise_of(claims: dict) -> str | None:
    """The exercise a launch opens: its custom ``exercise``, else ``?exercise=`` in its target link."""
    custom = claims.get(CLAIM + 'custom')
    found = custom.get('exercise') if isinstance(custom, dict) else None
    if not isinstance(found, str) or not found.strip():
        query = urllib.parse.urlsplit(str(claims.get(CLAIM + 'target_link_uri', ''))).query
        found = (urllib.parse.parse_qs(query).get('exercise') or [''])[0]
    return found.strip()[:100] or None


async def remember_launch(store: Store, person: str, claims: dict) -> bool:
    """Keep the line item of a resource link launch that carries the AGS claim; True if kept."""
    ags = claims.get(AGS_CLAIM) if isinstance(claims.get(AGS_CLAIM), dict) else {}
    lineitem = ags.get('lineitem')
    link = (claims.get(CLAIM + 'resource_link') or {}).get('id')
    if not isinstance(lineitem, str) or not isinstance(link, str):
        return False
    aud = claims.get('aud')
    client_id = aud[0] if isinstance(aud, list) else aud
    scopes = ags.get('scope') if isinstance(ags.get('scope'), list) else []
    row = dict(person=person, resource_link=link[:255], issuer=claims['iss'], client_id=str(client_id),
               subject=str(claims['sub']), lineitem=lineitem[:1000], launched=time.time(),
               exercise=exercise_of(claims), scopes=' '.join(str(x) for x in scopes)[:1000])

    def write(conn):
        conn.execute(LINKS.delete().where(LINKS.c.person == person, LINKS.c.resource_link == row['resource_link']))
        conn.execute(LINKS.insert().values(**row))
    await store.run(write)
    return True


async def link_of(store: Store, person: str, exercise: str) -> str | None:
    """The resource link of this person's newest launch of this exercise with a line item, or None."""
    return await store.run(lambda c: c.execute(
        sa.select(LINKS.c.resource_link).where(LINKS.c.person == person, LINKS.c.exercise == exercise)
        .order_by(LINKS.c.launched.desc()).limit(1)).scalar())


async def resolve(store: Store, config: LtiConfig, person: str) -> int:
    """Name the exercise of this person's launches that named none, by their line item's
    ``resourceId`` (what the deep link gave it), read from the platform; the number named."""
    rows = await store.run(lambda c: c.execute(sa.select(LINKS).where(
        LINKS.c.person == person, LINKS.c.exercise.is_(None))).mappings().all())
    named = 0
    for row in rows:
        reg = config.find(row['issuer'], row['client_id'])
        if reg is None:
            continue
        offered = row['scopes'].split()
        scopes = [x for x in (SCOPE_LINEITEM_READ, SCOPE_LINEITEM) if x in offered] or [SCOPE_LINEITEM_READ]
        token = await access_token(config, reg, scopes)
        resp = await AsyncHTTPClient().fetch(HTTPRequest(
            row['lineitem'], request_timeout=20, headers={'Accept': LINEITEM, 'Authorization': f'Bearer {token}'}))
        found = json.loads(resp.body).get('resourceId')
        if isinstance(found, str) and found.strip():
            await store.run(lambda c, r=row, f=found.strip()[:100]: c.execute(LINKS.update().where(
                LINKS.c.person == r['person'], LINKS.c.resource_link == r['resource_link']).values(exercise=f)))
            named += 1
    return named


async def post_result(store: Store, person: str, line_item_key: str, score: float, attempt_id: str,
                      now: float | None = None, comment: str | None = None) -> bool:
    """Queue the score (0..1) of one attempt for the LMS. True if queued now, False if this attempt
    was queued before (never twice). GradeError if the person did not launch from that line item."""
    if not 0.0 <= float(score) <= 1.0:
        raise GradeError(f'score {score!r} is outside 0..1')
    now = time.time() if now is None else now

    def write(conn):
        link = conn.execute(sa.select(LINKS.c.lineitem).where(
            LINKS.c.person == person, LINKS.c.resource_link == line_item_key)).first()
        if link is None:
            raise GradeError(f'{person} did not launch from line item {line_item_key!r}: no score is posted')
        if conn.execute(sa.select(OUTBOX.c.attempt_id).where(OUTBOX.c.attempt_id == attempt_id)).first():
            return False
        conn.execute(OUTBOX.insert().values(attempt_id=attempt_id, person=person, resource_link=line_item_key,
                                            score=float(score), created=now, tries=0, next_try=now,
                                            comment=(comment or '')[:200] or None))
        return True
    return await store.run(write)


def client_assertion(config: LtiConfig, reg: Registration, now: float | None = None) -> str:
    """The RFC 7523 JWT the tool proves itself with at the platform's token endpoint."""
    now = int(time.time() if now is None else now)
    kid, key = config.signing_key()
    payload = {'iss': reg.client_id, 'sub': reg.client_id, 'aud': reg.auth_token_url,
               'iat': now, 'exp': now + 300, 'jti': secrets.token_urlsafe(16)}
    return jwt.encode(payload, key, algorithm='RS256', headers={'kid': kid})


async def access_token(config: LtiConfig, reg: Registration, scopes: list[str]) -> str:
    if not reg.auth_token_url:
        raise GradeError(f'{reg.issuer}: auth_token_url (the platform\'s token endpoint) is not configured')
    body = urllib.parse.urlencode({
        'grant_type': 'client_credentials',
        'client_assertion_type': 'urn:ietf:params:oauth:client-assertion-type:jwt-bearer',
        'client_assertion': client_assertion(config, reg), 'scope': ' '.join(scopes)})
    resp = await AsyncHTTPClient().fetch(HTTPRequest(
        reg.auth_token_url, method='POST', body=body, request_timeout=20,
        headers={'Content-Type': 'application/x-www-form-urlencoded', 'Accept': 'application/json'}))
    return json.loads(resp.body)['access_token']


def _scores_url(lineitem: str) -> str:
    parts = urllib.parse.urlsplit(lineitem)
    return urllib.parse.urlunsplit(parts._replace(path=parts.path.rstrip('/') + '/scores'))


class Outbox(Hook):
    """Posts due scores: ``start`` flushes every ``period`` seconds on the running loop; ``on_attempt_ended``
    (the checker's event) queues an ended attempt's score and flushes at once."""

    def __init__(self, store: Store, config: LtiConfig):
        self.store, self.config = store, config
        self._timer = None
        self._lock = asyncio.Lock()
        self._tasks: set = set()

    def on_attempt_ended(self, identity, exercise, attempt) -> None:
        """An attempt ended (the checker's event) (on the loop; never raises into the checker)."""
        if identity is None or not getattr(identity, 'key', None):
            return   # no person (auth off, a token without a key): no LMS to tell
        task = asyncio.get_running_loop().create_task(self.queue(identity.key, exercise.id, attempt))
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def queue(self, person: str, exercise: str, attempt) -> bool:
        """Queue the attempt's score for the person's launch of the exercise, then flush; False
        when they launched from no line item of it (nothing is posted) or it was queued before."""
        try:
            link = await link_of(self.store, person, exercise)
            if link is None and await resolve(self.store, self.config, person):
                link = await link_of(self.store, person, exercise)
            if link is None:
                return False
            missed = getattr(attempt, 'missed', '')   # which part of the goal was not met
            comment = (f'{"passed" if attempt.passed else "failed"} ({attempt.why})'
                       + (f': {missed}' if missed else '') + f', attempt {attempt.attempt}')
            if len(comment) > 200:   # the outbox keeps 200 characters: the attempt's id stays whole
                comment = comment[:200 - len(attempt.attempt) - 11] + f'…, attempt {attempt.attempt}'
            queued = await post_result(self.store, person, link, attempt.score, attempt.attempt,
                                       now=attempt.ended_at, comment=comment)
        except Exception:
            log.exception('score of attempt %s not queued', attempt.attempt)
            return False
        if queued:
            await self.flush()
        return queued

    def start(self, period: float = BACKOFF_FIRST) -> None:
        self._timer = PeriodicCallback(self.flush, period * 1000)
        self._timer.start()

    async def stop(self, timeout: float = 5.0) -> None:
        """No more timed flushes; the results being queued are written (for at most ``timeout`` s)."""
        if self._timer is not None:
            self._timer.stop()
        if self._tasks:
            await asyncio.wait(list(self._tasks), timeout=timeout)

    async def flush(self, now: float | None = None) -> int:
        """Post every due score; the number posted."""
        async with self._lock:
            return await self._flush(time.time() if now is None else now)

    async def _flush(self, now: float) -> int:
        due = await self.store.run(lambda c: c.execute(
            sa.select(OUTBOX, LINKS.c.issuer, LINKS.c.client_id, LINKS.c.subject, LINKS.c.lineitem)
            .join(LINKS, sa.and_(LINKS.c.person == OUTBOX.c.person, LINKS.c.resource_link == OUTBOX.c.resource_link))
            .where(OUTBOX.c.posted.is_(None), OUTBOX.c.next_try <= now)).mappings().all())
        posted = 0
        for row in due:
            claimed = await self.store.run(lambda c, r=row: c.execute(   # another gateway of a fleet may flush too
                OUTBOX.update().where(OUTBOX.c.attempt_id == r['attempt_id'], OUTBOX.c.posted.is_(None),
                                      OUTBOX.c.next_try <= now).values(next_try=now + HOLD)).rowcount)
            if claimed != 1:
                continue
            try:
                await self._post(row)
            except (OSError, HTTPClientError, GradeError, KeyError, ValueError) as e:
                delay = min(BACKOFF_MAX, BACKOFF_FIRST * 2 ** row['tries'])
                log.warning('score for attempt %s not posted (%s); next try in %.0f s', row['attempt_id'], e, delay)
                await self.store.run(lambda c, r=row, d=delay, e=e: c.execute(
                    OUTBOX.update().where(OUTBOX.c.attempt_id == r['attempt_id'])
                    .values(tries=r['tries'] + 1, next_try=now + d, last_error=str(e)[:500])))
                continue
            await self.store.run(lambda c, r=row: c.execute(
                OUTBOX.update().where(OUTBOX.c.attempt_id == r['attempt_id']).values(posted=time.time())))
            posted += 1
        return posted

    async def _post(self, row) -> None:
        reg = self.config.find(row['issuer'], row['client_id'])
        if reg is None:
            raise GradeError(f'{row["issuer"]} is no longer registered')
        token = await access_token(self.config, reg, [SCOPE_SCORE])
        score = {
            'userId': row['subject'], 'scoreGiven': row['score'], 'scoreMaximum': 1.0,
            'activityProgress': 'Completed', 'gradingProgress': 'FullyGraded',
            'timestamp': datetime.fromtimestamp(row['created'], timezone.utc).isoformat(),
            'comment': row['comment'] or f'attempt {row["attempt_id"]}',
        }
        await AsyncHTTPClient().fetch(HTTPRequest(
            _scores_url(row['lineitem']), method='POST', body=json.dumps(score), request_timeout=20,
            headers={'Content-Type': 'application/vnd.ims.lis.v1.score+json', 'Authorization': f'Bearer {token}'}))
