"""Whose a share link is: the gateway signs a program for the person sharing it and says, to whoever
opens the link, who signed it.

POST /api/share        {"text": PROGRAM_JSON} -> {"by": NAME, "sig": SIG}  (nulls with auth off)
POST /api/share/check  {"text", "by", "sig"}  -> {"signed": bool, "by": NAME | null, "mine": bool}

A share link carries its program in the URL (``ide/js/editors/storage.js``); anyone can write one and put
any name in it. Opened by the teacher, a student's link ran its program with the teacher's whole
session. The page now asks before a link's program first runs and runs it without admin rights
(``ide/js/run/foreign.js``); to say whose it is, it asks here: ``sig`` is an HMAC of the signer's key,
name and the program's exact text under the gateway's own secret (the session cookies' secret,
``auth.sessions.cookie_secret``), so a name is shown only when this gateway signed it, and
``mine`` (the signer is the caller) is the one case that needs no asking. The signature itself is
``auth.signing``'s.
"""

from __future__ import annotations

import tornado.web

from ..auth.sessions import cookie_secret
from ..auth.signing import sign, signer
from ..rules.access import Action, Area
from .api import JsonHandler, authorized, body_json

MAX_TEXT = 3 * 2**20     # a program is at most 2 MiB (lab.programs.MAX_PROGRAM_BYTES) and its JSON some more


class _Handler(JsonHandler):
    def initialize(self, secret: bytes) -> None:
        self.secret = secret

    def _text(self, body: dict) -> str:
        text = body.get('text')
        if not isinstance(text, str):
            raise tornado.web.HTTPError(400, '"text" is the program\'s JSON text')
        return text


class ShareHandler(_Handler):
    @authorized(Area.SHARES, Action.SEE, origin=False)   # signing changes nothing
    def post(self) -> None:
        identity = self.identity
        text = self._text(body_json(self, MAX_TEXT))
        if identity is None:
            self.finish({'by': None, 'sig': None})
            return
        self.finish({'by': identity.name, 'sig': sign(self.secret, identity.owner, identity.name, text)})


class CheckHandler(_Handler):
    @authorized(Area.SHARES, Action.SEE, origin=False)   # signing changes nothing
    def post(self) -> None:
        identity = self.identity
        body = body_json(self, MAX_TEXT)
        text, by, sig = self._text(body), body.get('by'), body.get('sig')
        if not (isinstance(by, str) and isinstance(sig, str)) or identity is None:
            self.finish({'signed': False, 'by': None, 'mine': False})
            return
        key = signer(self.secret, sig, by, text)
        self.finish({'signed': key is not None, 'by': by if key is not None else None,
                     'mine': key is not None and key == identity.owner})


def share_routes(signed: bool) -> list:
    """``signed``: whether links are signed (auth is on: the session cookies' secret signs them)."""
    kw = {'secret': cookie_secret() if signed else b''}
    return [(r'/api/share', ShareHandler, kw), (r'/api/share/check', CheckHandler, kw)]
