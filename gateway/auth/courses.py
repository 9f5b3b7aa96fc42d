"""The LMS courses' members as the LMS last listed them (LTI Advantage NRPS): who is in which course,
with which roles, and whether they left it.

``lab.roster`` reads them from the LMS and writes them here (``lti_roster``: each member's person
key, the same ``lti-`` key a launch gives them, name, roles and status; ``lti_courses``: each
course's memberships URL and title). ``members`` lists them for the class view and the booking
panel; ``has_left`` tells the bookings (a rule) that a student who left the course can no longer
book. A person the LMS never listed (a local account) is not judged here.
"""

from __future__ import annotations

import sqlalchemy as sa

from ..store import METADATA, Store
from .lti import role_of

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

COURSES = sa.Table(
    'lti_courses', METADATA,
    sa.Column('url', sa.String(1000), primary_key=True),     # the course's context_memberships_url
    sa.Column('issuer', sa.String(255), nullable=False),
    sa.Column('client_id', sa.String(255), nullable=False),
    sa.Column('context', sa.String(255), nullable=False),
    sa.Column('title', sa.String(255), nullable=False),
    sa.Column('fetched', sa.Float, nullable=False),
)


async def members(store: Store) -> list[dict]:
    """Every course's members, for the class view and the booking panel: each with ``role`` as the
    gateway gives it at a launch (admin, operator, viewer) and the course's title."""
    rows = await store.run(lambda c: c.execute(
        sa.select(ROSTER, COURSES.c.title).outerjoin(COURSES, sa.and_(
            COURSES.c.issuer == ROSTER.c.issuer, COURSES.c.context == ROSTER.c.context))
        .order_by(ROSTER.c.context, ROSTER.c.name)).mappings().all())
    return [{**r, 'title': r['title'] or r['context'], 'role': role_of(r['roles'].split())} for r in rows]


async def has_left(store: Store, person: str) -> bool:
    """True if the LMS listed this person (their key, or a booking's ``user KEY``) and no course
    lists them active any more."""
    person = person.removeprefix('user ')
    statuses = await store.run(lambda c: c.execute(
        sa.select(ROSTER.c.status).where(ROSTER.c.person == person)).scalars().all())
    return bool(statuses) and 'Active' not in statuses
