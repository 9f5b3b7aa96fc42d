"""Who the security tests are: the tokens of a tokens file (one per role), its rosauth secret,
and signing in through /login."""

from __future__ import annotations

import hashlib
import urllib.parse

from tests.support.http import http

TOKENS = {
    'viewer': 'viewer-token-0a1b2c',
    'operator': 'operator-token-3d4e5f',
    'operator2': 'operator-token-6a7b8c',
    'admin': 'admin-token-9d0e1f',
}
ROSAUTH_SECRET = 'rosauth-shared-secret-42'


def tokens_toml() -> str:
    sha = hashlib.sha256(TOKENS['admin'].encode()).hexdigest()
    return f'''
[[tokens]]
name = "vera"
role = "viewer"
token = "{TOKENS['viewer']}"

[[tokens]]
name = "alice"
role = "operator"
token = "{TOKENS['operator']}"

[[tokens]]
name = "bob"
role = "operator"
token = "{TOKENS['operator2']}"

[[tokens]]
name = "teacher"
role = "admin"
sha256 = "{sha}"

[rosauth]
secret = "{ROSAUTH_SECRET}"
role = "viewer"
'''


def login(gw, token: str, headers: dict | None = None) -> str:
    """Signs in through the /login form; the session cookie's ``name=value``."""
    form = urllib.parse.urlencode({'token': token, 'next': '/'}).encode()
    reply = http(gw, '/login', method='POST', data=form, headers=headers)
    assert reply.status == 303, reply
    return reply.headers['Set-Cookie'].split(';', 1)[0]
