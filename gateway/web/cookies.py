"""Cookies the gateway sets, with the attributes today's browsers need.

Written as Set-Cookie headers here because Python's ``http.cookies`` (under tornado's
``set_cookie``) knows no ``Partitioned`` before 3.14. ``Partitioned`` (CHIPS) is what lets a cookie
live inside another site's iframe (an LMS page) now that Chromium blocks unpartitioned
third-party cookies, even ``SameSite=None; Secure`` ones; browsers require ``Secure`` with it and
with ``SameSite=None``.
"""

from __future__ import annotations

import tornado.web


def set_cookie(handler: tornado.web.RequestHandler, name: str, value: str, *, max_age: int | None,
               samesite: str = 'Lax', secure: bool = False, partitioned: bool = False, path: str = '/') -> None:
    parts = [f'{name}={value}', f'Path={path}', 'HttpOnly', f'SameSite={samesite}']
    if max_age is not None:
        parts.append(f'Max-Age={max_age}')
    if secure or partitioned or samesite == 'None':
        parts.append('Secure')
    if partitioned:
        parts.append('Partitioned')
    handler.add_header('Set-Cookie', '; '.join(parts))


def clear_cookie(handler: tornado.web.RequestHandler, name: str, *, secure: bool = False, path: str = '/') -> None:
    """Gone from the browser, both the first-party cookie and a partitioned one of this site."""
    set_cookie(handler, name, '', max_age=0, secure=secure, path=path)
    if secure:
        set_cookie(handler, name, '', max_age=0, samesite='None', partitioned=True, path=path)


def is_https(handler: tornado.web.RequestHandler) -> bool:
    """Whether the browser reached the gateway over https (directly, or through a trusted proxy)."""
    return handler.request.protocol == 'https'
