"""A share link's signature: who shared a program, as this gateway vouches for it.

``sign(secret, key, name, text)``: the signer's key (base64) and an HMAC-SHA256 of that key, the name
shown and the program's exact text under the gateway's own secret (the session cookies',
``sessions.cookie_secret``); ``signer(secret, sig, name, text)``: whose key signed ``text`` as
``name``, or None when this gateway did not. The HTTP API is ``web.share``.
"""

from __future__ import annotations

import base64
import hashlib
import hmac


def _mac(secret: bytes, key: str, name: str, text: str) -> str:
    data = b'\0'.join((b'rosgate share link', key.encode(), name.encode(), text.encode()))
    return hmac.new(secret, data, hashlib.sha256).hexdigest()


def sign(secret: bytes, key: str, name: str, text: str) -> str:
    return base64.urlsafe_b64encode(key.encode()).decode().rstrip('=') + '.' + _mac(secret, key, name, text)


def signer(secret: bytes, sig: str, name: str, text: str) -> str | None:
    """The key of who signed ``text`` as ``name`` with ``sig``, or None when this gateway did not."""
    encoded, _, mac = sig.partition('.')
    try:
        key = base64.urlsafe_b64decode(encoded + '=' * (-len(encoded) % 4)).decode()
    except ValueError:
        return None
    return key if hmac.compare_digest(mac, _mac(secret, key, name, text)) else None
