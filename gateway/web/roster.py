"""The course's roster from the LMS (LTI Advantage NRPS, ``lab.roster``) for the teacher's pages:

GET  /api/roster  -> {"enabled", "members": [{"person", "name", "role", "roles", "status", "context",
                     "title", "fetched"}], "courses": N}: every course's members as the LMS last listed
                     them (status Active, Inactive, or Deleted: gone from the LMS's list); admins only
POST /api/roster  -> the same after reading every known course's roster again (the teacher's
                     "Refresh"), with "failed": {url: why} for those the LMS did not answer

The class view lists them before a student first launches (a course's roster is read at each
launch of it, the teacher's included, and at start for a registration's ``memberships_urls``);
the booking panel offers them to book for (``bookings.PeopleHandler``).
"""

from __future__ import annotations

import tornado.web

from ..auth import courses
from ..lab import roster
from ..rules.access import Area
from ..store import Store
from .api import JsonHandler, authorized


class RosterHandler(JsonHandler):
    def initialize(self, store: Store, config) -> None:
        self.store, self.config = store, config

    @authorized(Area.ROSTER)
    async def get(self) -> None:
        await self._answer({})

    @authorized(Area.ROSTER)
    async def post(self) -> None:
        if self.config is None:
            raise tornado.web.HTTPError(404, 'no LMS to read a roster from (start the gateway with --lti)')
        await self._answer(await roster.refresh(self.store, self.config))

    async def _answer(self, failed: dict) -> None:
        members = await courses.members(self.store)
        self.finish({'enabled': self.config is not None, 'members': members,
                     'courses': len({(m['issuer'], m['context']) for m in members}), 'failed': failed})


def roster_routes(store: Store, config) -> list:
    return [(r'/api/roster/?', RosterHandler, {'store': store, 'config': config})]
