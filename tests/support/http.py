"""HTTP requests to a gateway: one request function (no redirect followed, so a test sees the 303
of /login itself), and its JSON form for the /api routes."""

from __future__ import annotations

import json as _json
import urllib.error
import urllib.request
from email.message import Message
from typing import NamedTuple


class Reply(NamedTuple):
    status: int
    body: bytes
    headers: Message

    def json(self):
        return _json.loads(self.body) if self.body else None


class _NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *args, **kw):
        return None


_OPENER = urllib.request.build_opener(_NoRedirect)


def http(gw, path: str, *, method: str = 'GET', data: bytes | None = None, json=None, token: str | None = None,
         headers: dict | None = None, host: str | None = None, timeout: float = 10) -> Reply:
    """A request to ``gw`` (anything with an ``http_url``): ``data`` as the body, or ``json`` sent as
    application/json; ``token`` as a bearer; ``host`` as the Host header. Errors are replies too."""
    if json is not None:
        data = _json.dumps(json).encode()
    request = urllib.request.Request(gw.http_url.rstrip('/') + path, data=data, method=method)
    if json is not None:
        request.add_header('Content-Type', 'application/json')
    if token:
        request.add_header('Authorization', f'Bearer {token}')
    if host:
        request.add_header('Host', host)
    for name, value in (headers or {}).items():
        request.add_header(name, value)
    try:
        with _OPENER.open(request, timeout=timeout) as res:
            return Reply(res.status, res.read(), res.headers)
    except urllib.error.HTTPError as e:
        return Reply(e.code, e.read(), e.headers)


def api(gw, method: str, path: str, body=None, token: str | None = None, headers=None):
    """(status, decoded JSON body) of a JSON API request."""
    reply = http(gw, path, method=method, json=body, token=token, headers=headers)
    return reply.status, reply.json()
