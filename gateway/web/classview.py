"""GET /class: the teacher's view of every robot station (ide/class.html).

When the gateway requires tokens (--auth) only an admin gets the page: without a token the
browser is sent to /login (and back here after signing in), other roles get 403.
"""

from __future__ import annotations

from urllib.parse import quote

import tornado.web

from ..rules.access import Area
from .api import Handler, authorize
from .pages import write_page


class ClassHandler(Handler):
    def initialize(self, page) -> None:
        self.page = page

    def get(self) -> None:
        try:
            authorize(self, Area.CLASS, words='the class view is for admins; {name} is {role}')
        except tornado.web.HTTPError as e:
            if e.status_code != 401:
                raise
            self.redirect(f'/login?next={quote("/class")}')
            return
        write_page(self, self.page, cache='no-store')

    def answer_error(self, status_code: int, reason: str) -> None:
        shown = reason if reason != self._reason else 'the class view cannot be shown'
        self.set_header('Content-Type', 'text/plain; charset=UTF-8')
        self.finish(f'{status_code} {self._reason}: {shown}\n'
                    'Sign in as an admin at /login?next=/class\n')
