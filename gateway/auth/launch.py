"""An LTI launch's single-use values and the platforms' keys: what ``web.lti``'s login and launch
keep between the two requests.

``Expiring``: single-use values by key (a login's state and nonce, a used state, a resume ticket, a
deep linking pick), each forgotten after its time, bounded. ``KeySets``: the platforms' public keys
by JWKS URL, fetched once and again for a key id not in them, with a bound on fetches.
"""

from __future__ import annotations

import json
import logging
import time
from collections import OrderedDict

import jwt
import tornado.httpclient

from . import lti
from .lti import LaunchError

log = logging.getLogger('rosgate.lti')
MAX_PENDING = 10000      # logins in flight kept at most (the oldest are forgotten)
JWKS_REFRESH = 60.0      # s before a key id missing from a platform's JWKS makes it fetched again
JWKS_FETCHES = 10        # fetches of one platform's JWKS a minute at most


class Expiring:
    """Single-use values by key, each forgotten after ``ttl`` s; bounded."""

    def __init__(self, ttl: float, limit: int = MAX_PENDING):
        self.ttl, self.limit, self.items = ttl, limit, OrderedDict()

    def put(self, key: str, value) -> None:
        self.items[key] = (time.monotonic() + self.ttl, value)
        while len(self.items) > self.limit:
            self.items.popitem(last=False)

    def take(self, key: str):
        entry = self.items.pop(key, None)
        if entry is None or entry[0] < time.monotonic():
            return None
        return entry[1]


class KeySets:
    """The platforms' public keys by JWKS URL: fetched once, and again when a launch names a key id
    not in them (a platform rotating its keys). A key id still missing after its fetch is not asked
    for again for ``JWKS_REFRESH`` s, and all the fetches of one URL together stay under
    ``JWKS_FETCHES`` a minute: launches with made-up key ids cannot make the gateway a flood."""

    def __init__(self):
        self.sets: dict[str, jwt.PyJWKSet] = {}
        self.missed: dict[tuple[str, str | None], float] = {}
        self.fetches: dict[str, list[float]] = {}

    async def key(self, reg: lti.Registration, kid: str | None):
        if reg.key_set is not None and not reg.key_set_url:
            return self._pick(jwt.PyJWKSet.from_dict(reg.key_set), kid, reg)
        url = reg.key_set_url
        keys = self.sets.get(url)
        found = self._find(keys, kid) if keys is not None else None
        now = time.monotonic()
        recent = [t for t in self.fetches.get(url, []) if now - t < 60]
        self.fetches[url] = recent
        if (found is None and now - self.missed.get((url, kid), -1e9) > JWKS_REFRESH
                and len(recent) < JWKS_FETCHES):
            recent.append(now)
            try:
                response = await tornado.httpclient.AsyncHTTPClient().fetch(url, request_timeout=10)
                keys = self.sets[url] = jwt.PyJWKSet.from_dict(json.loads(response.body))
            except Exception as e:
                log.warning('lti: cannot fetch the keys of %s from %s: %s', reg.issuer, url, e)
                raise LaunchError(f'cannot fetch the platform\'s keys from {url}: {e}') from None
            found = self._find(keys, kid)
            if found is None:
                if len(self.missed) > MAX_PENDING:
                    self.missed.clear()
                self.missed[(url, kid)] = now
        if found is None:
            raise LaunchError(f'the id_token is signed with a key ({str(kid)[:60]}) the platform does not publish '
                              f'at {url}')
        return found

    @staticmethod
    def _find(keys, kid):
        for k in keys.keys:
            if kid is None or k.key_id == kid:
                return k.key
        return None

    def _pick(self, keys, kid, reg):
        found = self._find(keys, kid)
        if found is None:
            raise LaunchError(f'the id_token is signed with a key ({str(kid)[:60]}) not in key_set for {reg.issuer}')
        return found
