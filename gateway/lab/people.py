"""Who an admin may book for: everyone who signed in here, then the LMS courses' active members who
never launched yet (``people``). The HTTP API is ``web.bookings`` (GET /api/people, and a booking's
"for").
"""

from __future__ import annotations

from ..auth import courses
from ..auth.sessions import Sessions
from ..store import Store


async def people(sessions: Sessions | None, store: Store, who: str | None = None) -> list[dict]:
    """Who an admin may book for: who signed in here (``sessions``: None with auth off), newest first,
    then the courses' active members who have not (``auth.courses``); ``who``: only those it names
    (their id, or their name in any case)."""
    found = [p.json() for p in sessions.people(who)] if sessions is not None else []
    seen = {p['id'] for p in found}
    for m in await courses.members(store):
        if m['status'] == 'Active' and m['person'] not in seen and (
                who is None or who == m['person'] or who.casefold() == m['name'].casefold()):
            seen.add(m['person'])
            found.append({'id': m['person'], 'name': m['name'], 'role': m['role'], 'kind': 'lti', 'seen': None})
    return found
