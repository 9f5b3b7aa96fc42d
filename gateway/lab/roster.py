"""The course's roster from the LMS (LTI Advantage, Names and Role Provisioning Services).

``fetch`` reads a course's memberships (the launch claim's ``context_memberships_url``) with the
tool's own client-credentials token (``grades.access_token``) and keeps them per (issuer, context):
each member's person key (the same ``lti-`` key a launch gives them), name, roles and status. A
member the LMS marks Inactive, or who is gone from the latest fetch, is kept as left; ``has_left``
tells bookings so that a student who left the course can no longer book (both kept and read in
``auth.courses``). A person the LMS never listed (a local account) is not judged here.

Each course's memberships URL is kept (``lti_courses``), so ``refresh`` reads every known course
again when the teacher asks (POST /api/roster); a launch of the course reads its own roster again
beside the launch (``web.lti``). A registration's ``memberships_urls`` (the tool configuration)
names courses to read at the gateway's start, before anyone launched.
"""

from __future__ import annotations

import json
import logging
import re
import time

import sqlalchemy as sa
from tornado.httpclient import AsyncHTTPClient, HTTPRequest

from ..auth.courses import COURSES, ROSTER
from ..store import Store
from .grades import access_token
from ..auth.lti import LtiConfig, Registration, identity_of

log = logging.getLogger('rosgate.roster')

NRPS_CLAIM = 'https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice'
SCOPE_MEMBERSHIPS = 'https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly'
MEMBERSHIPS = 'application/vnd.ims.lti-nrps.v2.membershipcontainer+json'
NEXT = re.compile(r'<([^>]+)>\s*;\s*rel="?next"?')
MAX_PAGES = 200


async def fetch(store: Store, config: LtiConfig, reg: Registration, url: str) -> int:
    """Read and keep the roster at ``url``; the number of members listed."""
    token = await access_token(config, reg, [SCOPE_MEMBERSHIPS])
    course, listed, page = {}, [], url
    for _ in range(MAX_PAGES):   # Canvas answers 10 members a page: the rest are at Link rel="next"
        resp = await AsyncHTTPClient().fetch(HTTPRequest(
            page, request_timeout=20, headers={'Accept': MEMBERSHIPS, 'Authorization': f'Bearer {token}'}))
        body = json.loads(resp.body)
        course = course or (body.get('context') if isinstance(body.get('context'), dict) else {})
        listed += body.get('members') or []
        page = next((m.group(1) for m in NEXT.finditer(resp.headers.get('Link', ''))), None)
        if page is None:
            break
    else:
        raise ValueError(f'the roster at {url[:200]} has more than {MAX_PAGES} pages')
    context = str(course.get('id') or url)[:255]
    now = time.time()
    rows = []
    for m in listed:
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
        conn.execute(COURSES.delete().where(COURSES.c.url == url[:1000]))
        conn.execute(COURSES.insert().values(url=url[:1000], issuer=reg.issuer, client_id=reg.client_id,
                                             context=context, title=str(course.get('title') or context)[:255],
                                             fetched=now))
    await store.run(write)
    return len(rows)


async def refresh(store: Store, config: LtiConfig) -> dict[str, str]:
    """Read every known course's roster again (and the configured ``memberships_urls``);
    {url: what went wrong} for those not read (the LMS down: the last roster stays)."""
    known = await store.run(lambda c: c.execute(sa.select(COURSES.c.url, COURSES.c.issuer, COURSES.c.client_id))
                            .all())
    urls = {url: (iss, client) for url, iss, client in known}
    for reg in config.registrations:
        for url in reg.memberships_urls:
            urls.setdefault(url, (reg.issuer, reg.client_id))
    failed = {}
    for url, (issuer, client_id) in urls.items():
        reg = config.find(issuer, client_id)
        try:
            if reg is None:
                raise LookupError(f'{issuer} is no longer registered')
            await fetch(store, config, reg, url)
        except Exception as e:   # one course's LMS down leaves the others read
            log.warning('roster at %s not read: %s', url[:200], e)
            failed[url] = str(e)[:300]
    return failed
