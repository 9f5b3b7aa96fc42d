"""Shared parts of the JSON HTTP API (/api/runs, /api/recordings, /api/programs, /whoami): errors
as JSON, who is asking (``@authorized``, the access decision in front of every handler method), and
the checks in front of every request that changes something."""

from __future__ import annotations

import functools
import json
import math
from typing import Protocol

import tornado.web
from tornado.log import gen_log

from ..rules.errors import Refusal
from ..rules.access import NOBODY, Action, Area, decide
from ..auth.tokens import AuthError, Authenticator, Identity


class Access(Protocol):
    """What ``@authorized`` reads of the gateway's policy (``rules.policy.Policy`` is one): whether
    auth is on, who a request is, and whether a browser origin may change things."""
    auth: Authenticator | None

    def identity_of(self, request) -> Identity | None: ...

    def origin_allowed(self, origin: str, request) -> bool: ...


class Handler(tornado.web.RequestHandler):
    """Every handler's errors, answered in one place: an HTTPError's message, or a refusal of the
    domain (``rules.errors.Refusal``: a booking, a run, a recording) with its own status, is the
    answer's reason; ``answer_error`` says how it is written (JSON here)."""

    def write_error(self, status_code: int, **kwargs) -> None:
        exc = kwargs.get('exc_info')
        error, reason = exc[1] if exc else None, None
        if isinstance(error, Refusal):
            status_code, reason = error.status, error.message
            self.set_status(status_code)
        elif isinstance(error, tornado.web.HTTPError):
            reason = error.log_message
        self.answer_error(status_code, reason or self._reason)

    def answer_error(self, status_code: int, reason: str) -> None:
        self.finish(json.dumps({'error': reason, 'status': status_code}))

    def log_exception(self, typ, value, tb) -> None:
        if isinstance(value, Refusal):      # an answer, not a fault: logged as tornado logs an HTTPError
            gen_log.warning('%d %s: %s', value.status, self._request_summary(), value.message)
        else:
            super().log_exception(typ, value, tb)


class JsonHandler(Handler):
    def set_default_headers(self) -> None:
        self.set_header('Content-Type', 'application/json; charset=utf-8')
        self.set_header('Cache-Control', 'no-store')


def authorized(area: Area, action: Action | None = None, words: str | None = None, origin: bool | None = None):
    """A handler method's access decision, as Jupyter Server's ``@authorized``: the caller is read
    once (``authorize``: a token, or the session cookie; 401 or 429), a method other than GET and
    HEAD passes the Origin check (``origin``: whether to, if not so), and ``rules.access.decide`` answers for ``action`` in ``area``
    (None: SEE for GET and HEAD, CHANGE for the others); a refusal is the HTTPError of its
    status and words (``words``: a 403's own, formatted with the caller's ``name`` and ``role``). The method finds the caller's Identity in ``self.identity`` (None: --auth off)."""
    def wrap(method):
        @functools.wraps(method)
        def guarded(self, *args, **kwargs):
            self.identity = authorize(self, area, action, words, origin)
            return method(self, *args, **kwargs)
        return guarded
    return wrap


def authorize(handler: tornado.web.RequestHandler, area: Area, action: Action | None = None,
              words: str | None = None, origin: bool | None = None):
    """``@authorized`` for a method that must answer something else first (the caller's Identity,
    None when auth is off)."""
    reads = handler.request.method in ('GET', 'HEAD')
    action = action or (Action.SEE if reads else Action.CHANGE)
    policy = policy_of(handler)
    if not reads if origin is None else origin:
        check_origin(handler, policy)
    identity = require(handler, policy)
    why = decide(identity if identity is not None or policy.auth is None else NOBODY, action, area)
    if why is not None:
        said = words.format(name=identity.name, role=identity.role) if words and why.status == 403 else why.message
        raise tornado.web.HTTPError(why.status, said)
    return identity


def policy_of(handler: tornado.web.RequestHandler) -> Access:
    """The gateway's policy: the handler's own, or its application's (``pages.Application``)."""
    policy = getattr(handler, 'policy', None)
    return policy if policy is not None else handler.application.policy


def check_origin(handler: tornado.web.RequestHandler, policy: Access) -> None:
    """A request that changes something comes from the gateway's own pages, an allowed browser
    origin, or no browser, whatever its body (empty ones included). As for the websocket
    (tornado's check): a browser's Sec-Fetch-Site of same-origin is its own word that the page
    shares the gateway's origin (which holds behind a TLS proxy too, where scheme and port differ
    from what the gateway sees); otherwise Origin must pass ``origin_allowed`` (scheme, host and
    port); a browser request that says it is from another site and sends no Origin is refused."""
    headers = handler.request.headers
    site = headers.get('Sec-Fetch-Site', '').lower()
    if site in ('same-origin', 'none'):
        return
    origin = headers.get('Origin')
    if origin is None and not site:
        return   # no browser
    if origin is None or not policy.origin_allowed(origin, handler.request):
        where = origin[:100] if origin is not None else f'another site ({site[:20]})'
        raise tornado.web.HTTPError(403, f'requests from {where} are not allowed (--allowed-origins)')


def body_json(handler: tornado.web.RequestHandler, limit: int) -> dict:
    """The request body as a JSON object (sent as application/json, so browsers of other
    origins cannot send it without a preflight that this server never grants)."""
    body = handler.request.body
    if len(body) > limit:
        raise tornado.web.HTTPError(413, f'body larger than {limit} bytes')
    kind = handler.request.headers.get('Content-Type', '').split(';')[0].strip().lower()
    if kind != 'application/json':
        raise tornado.web.HTTPError(415, 'send the body as application/json')
    try:
        value = json.loads(body)
    except ValueError as e:
        raise tornado.web.HTTPError(400, f'body is not JSON: {e}') from None
    except RecursionError:   # deeper than the parser goes: it was a 500 with a traceback
        raise tornado.web.HTTPError(400, f'body: nested deeper than {MAX_DEPTH} levels') from None
    if not isinstance(value, dict):
        raise tornado.web.HTTPError(400, 'the body is a JSON object')
    for key, item in value.items():
        if depth(item) > MAX_DEPTH - 1:
            raise tornado.web.HTTPError(400, f'"{str(key)[:64]}" is nested deeper than {MAX_DEPTH} levels')
    return value


MAX_DEPTH = 512   # levels of a JSON body: a stack of 250 blocks nests 500 deep (each "next" is two)


def depth(value) -> int:
    """How deep a JSON value nests (a scalar: 0), without recursion."""
    deepest, todo = 0, [(value, 1)]
    while todo:
        item, level = todo.pop()
        children = item.values() if isinstance(item, dict) else item if isinstance(item, list) else None
        if children is None:
            continue
        deepest = max(deepest, level)
        if level > MAX_DEPTH:
            return level
        todo.extend((child, level + 1) for child in children)
    return deepest


def query_number(handler: tornado.web.RequestHandler, name: str, default, what: str, *, kind=float,
                 low: float = -math.inf, high: float = math.inf, blank: tuple[str, ...] = ('',)):
    """``?name=`` as a finite number of ``kind`` (float or int) from ``low`` to ``high``: ``default``
    when it is absent or one of ``blank``, a 400 saying it is ``what`` otherwise. Every API's
    query numbers are read here."""
    text = handler.get_query_argument(name, None)
    if text is None or text.strip() in blank:
        return default
    try:
        value = kind(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and low <= value <= high):
        raise tornado.web.HTTPError(400, f'"{name}" is {what}, not {text[:40]!r}')
    return value


def require(handler: tornado.web.RequestHandler, policy: Access, area: Area = Area.WHOAMI):
    """The caller's Identity (None when auth is off); raise 401 (no or bad token), 429 (too many
    failures), or what ``decide`` says of SEE in ``area``."""
    if policy.auth is None:
        return None
    try:
        identity = policy.identity_of(handler.request)
    except AuthError as e:
        raise tornado.web.HTTPError(e.status, str(e)) from None
    why = decide(identity if identity is not None else NOBODY, Action.SEE, area)
    if why is not None:
        raise tornado.web.HTTPError(why.status, why.message)
    return identity
