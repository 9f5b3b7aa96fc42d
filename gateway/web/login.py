"""Signing in: a small login page that begins a session (its cookie is a signed session id, never
the token: ``auth.sessions``), sign-out that ends it on the server, and /whoami."""

from __future__ import annotations

import html
from urllib.parse import unquote

import tornado.web

from ..rules.policy import session_cookie
from ..auth.sessions import SESSION_COOKIE
from ..auth.tokens import AuthError
from ..rules.access import Area
from .api import JsonHandler, authorized, check_origin
from .cookies import clear_cookie, is_https, set_cookie
from .language import Texts

PAGE = """<!doctype html>
<html lang="{lang}" dir="{dir}"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width">
<title>{title}</title>
<style>body{{font:16px system-ui,sans-serif;max-width:22rem;margin:4rem auto;padding:0 1rem}}
input,button{{font:inherit;width:100%;box-sizing:border-box;padding:.5rem;margin:.3rem 0}}
.msg{{color:#a00}}</style></head>
<body><h1>rosgate</h1><p>{intro}</p><p class="msg">{message}</p>
<form method="post" action="/login"><input type="hidden" name="next" value="{next}">
<label>{token} <input name="token" type="password" autocomplete="current-password" autofocus></label>
<button type="submit">{submit}</button></form></body></html>
"""


def _safe_next(value: str) -> str:
    """Only a path of this server, never another site: one slash then no second one, no backslash, and
    nothing a browser drops from a URL (tabs, newlines, spaces and other controls: /%09/evil was
    //evil to the browser, another site)."""
    def bad(text: str) -> bool:
        return text[:1] != '/' or text[1:2] in ('/', '\\') or '\\' in text or len(text) > 2048 \
            or any(ord(c) <= 0x20 or 0x7f <= ord(c) <= 0x9f for c in text)
    return '/' if bad(value) or bad(unquote(value)) else value   # nor its percent-encoded form


class LoginHandler(tornado.web.RequestHandler):
    def initialize(self, policy, texts: Texts) -> None:
        self.policy = policy
        self.texts = texts

    def set_default_headers(self) -> None:
        self.set_header('Cache-Control', 'no-store')
        self.set_header('Content-Security-Policy', "default-src 'none'; style-src 'unsafe-inline'; form-action 'self'")

    def _page(self, message: str = '', status: int = 200) -> None:
        self.set_status(status)
        lang = self.texts.pick(self)

        def say(key: str) -> str:
            return html.escape(self.texts.get(lang, key))
        intro = say('login.intro' if self.policy.auth is not None else 'login.intro.open')
        nxt = _safe_next(self.get_argument('next', '/'))
        self.finish(PAGE.format(lang=lang, dir=self.texts.direction(lang), title=say('login.title'), intro=intro,
                                token=say('login.token'), submit=say('login.submit'),
                                message=html.escape(message), next=html.escape(nxt)))

    def get(self) -> None:
        self._page()

    def post(self) -> None:
        # a form on another site must not sign this browser in as someone else (login CSRF)
        check_origin(self, self.policy)
        auth = self.policy.auth
        if auth is None:
            self.redirect(_safe_next(self.get_argument('next', '/')))
            return
        try:
            identity = auth.token(self.request.remote_ip or '?', self.get_argument('token', ''))
        except AuthError as e:
            self._page(str(e), e.status)
            return
        begin_session(self, self.policy, identity, 'token')
        self.set_header('X-Rosgate-Role', identity.role)
        self.redirect(_safe_next(self.get_argument('next', '/')), status=303)


class LogoutHandler(tornado.web.RequestHandler):
    def initialize(self, policy) -> None:
        self.policy = policy

    async def get(self) -> None:
        check_origin(self, self.policy)
        why = None
        if self.policy.sessions is not None:   # answered once every gateway refuses the session
            why = await self.policy.sessions.sign_out(session_cookie(self.request))
        clear_cookie(self, SESSION_COOKIE, secure=is_https(self))
        if why is not None:
            self.set_status(503)
            self.set_header('Content-Type', 'text/plain; charset=utf-8')
            self.finish(why)
            return
        self.redirect('/login', status=303)

    post = get


class WhoAmIHandler(JsonHandler):
    """{"auth": bool, "name", "role"} for the token this browser holds (the IDE hides what the
    role may not use); 401 when auth is on and no valid token came with the request."""

    def initialize(self, policy) -> None:
        self.policy = policy

    @authorized(Area.WHOAMI)
    def get(self) -> None:
        identity = self.identity
        if identity is None:   # --auth off
            self.finish({'auth': False, 'name': None, 'role': 'admin'})
            return
        self.finish({'auth': True, 'name': identity.name, 'role': identity.role})


def begin_session(handler: tornado.web.RequestHandler, policy, identity, kind: str, *, framed: bool = False) -> None:
    """Sign this browser in as ``identity``: a new session and its cookie. SameSite=Lax, so the
    cookie comes along when a link or an LMS brings the browser here; ``framed`` (a launch inside
    an LMS's iframe): SameSite=None; Secure; Partitioned, the only kind Chromium keeps there."""
    value = policy.sessions.begin(identity, kind)
    max_age = int(policy.sessions.seconds)
    if framed:
        set_cookie(handler, SESSION_COOKIE, value, max_age=max_age, samesite='None', partitioned=True)
    else:
        set_cookie(handler, SESSION_COOKIE, value, max_age=max_age, samesite='Lax', secure=is_https(handler))


def login_routes(policy, texts: Texts) -> list:
    kw = {'policy': policy, 'texts': texts}
    return [(r'/login/?', LoginHandler, kw), (r'/logout/?', LogoutHandler, {'policy': policy}),
            (r'/whoami', WhoAmIHandler, {'policy': policy})]
