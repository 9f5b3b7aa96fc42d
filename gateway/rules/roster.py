"""The course's roster from the LMS (LTI Advantage, Names and Role Provisioning Services).

``fetch`` reads a course's memberships (the launch claim's ``context_memberships_url``) with the
tool's own client-credentials token (``grades.access_token``) and keeps them per (issuer, context):
each member's person key (the same ``lti-`` key a launch gives them), name, roles and status. A
member the LMS marks Inactive, or who is gone from the latest fetch, is kept as left; ``has_left``
tells bookings so that a student who left the course can no longer book. A person the LMS never
listed (a local account) is not judged here.
"""

from __future__ import annotations

import json
import time

import sqlalchemy as sa
from tornado.httpclient import AsyncHTTPClient, HTTPRequest

from ..store import METADATA, Store
from .grades import access_token
from .lti import LtiConfig, Registration, identity_of

NRPS_CLAIM = 'https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice'
SCOPE_MEMBERSHIPS = 'https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly'
MEMBERSHIPS = 'application/vnd.ims.lti-nrps.v2.membershipcontainer+json'

ROSTER = sa.Table(
    'lti_roster', METADATA,
    sa.Column('issuer', sa.String(255), primary_key=True),
    sa.Column('context', sa.String(255), primary_key=True),
    sa.Column('person', sa.String(64), primary_key=True),
    sa.Column('name', sa.String(100), nullable=False),
    sa.Column('roles', sa.String(1000), nullable=False),
    sa.Column('status', sa.String(20), nullable=False),   # Active, Inactive, Deleted (gone from the LMS)
    sa.Column('fetched', sa.Float, nullable=False),
)


async def fetch(store: Store, config: LtiConfig, reg: Registration, url: str) -> int:
    """Read and keep the roster at ``url``; the number of members listed."""
    token = await access_token(config, reg, [SCOPE_MEMBERSHIPS])
    resp = await AsyncHTTPClient().fetch(HTTPRequest(
        url, request_timeout=20, headers={'Accept': MEMBERSHIPS, 'Authorization': f'Bearer {token}'}))
    body = json.loads(resp.body)
    context = str((body.get('context') or {}).get('id') or url)[:255]
    now = time.time()
    rows = []
    for m in body.get('members') or []:
        if not isinstance(m, dict) or not m.get('user_id'):
            continue
        who = identity_of({'iss': reg.issuer, 'sub': str(m['user_id']), 'name': m.get('name'),
                           'given_name': m.get('given_name'), 'family_name': m.get('family_name'),
                           'email': m.get('email')})
        rows.append(dict(issuer=reg.issuer, context=context, person=who.key, name=who.name,
                         roles=' '.join(str(r) for r in m.get('roles') or [])[:1000],
                         status=str(m.get('status') or 'Active')[:20], fetched=now))

    def write(conn):
        where = (ROSTER.c.issuer == reg.issuer) & (ROSTER.c.context == context)
        conn.execute(ROSTER.update().where(where).values(status='Deleted', fetched=now))
        for row in rows:
            conn.execute(ROSTER.delete().where(where & (ROSTER.c.person == row['person'])))
            conn.execute(ROSTER.insert().values(**row))
    await store.run(write)
    return len(rows)


async def members(store: Store) -> list[dict]:
    """Every course's members, for the class view and the booking panel."""
    rows = await store.run(lambda c: c.execute(sa.select(ROSTER).order_by(ROSTER.c.context, ROSTER.c.name))
                           .mappings().all())
    return [dict(r) for r in rows]


async def has_left(store: Store, person: str) -> bool:
    """True if the LMS listed this person and no course lists them active any more."""
    statuses = await store.run(lambda c: c.execute(
        sa.select(ROSTER.c.status).where(ROSTER.c.person == person)).scalars().all())
    return bool(statuses) and 'Active' not in statuses
