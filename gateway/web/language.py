"""The gateway's own pages (the login page) in the reader's language, from the same files as the
IDE's pages: ``ide/i18n/<lang>.json`` (flat keys to strings with ``{name}`` placeholders) and
``ide/i18n/languages.json`` (the languages offered). A string missing from a language, or a
language whose file is missing, falls back to English, as in ``ide/js/i18n.js``.

The language is ``?lang=``, else the choice the pages' language menu remembers (the
``rosgate-lang`` cookie it sets), else the browser's Accept-Language; English otherwise.
The login page runs no script (its CSP forbids them), so it is translated here.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

log = logging.getLogger(__name__)

COOKIE = 'rosgate-lang'   # set by ide/js/i18n.js's menu


def accepted(header: str) -> list[str]:
    """The tags of an Accept-Language header, most wanted first (q=0 left out)."""
    tags = []
    for i, part in enumerate(header.split(',')):
        tag, _, params = part.strip().partition(';')
        q = 1.0
        if params.strip().startswith('q='):
            try:
                q = float(params.strip()[2:])
            except ValueError:
                q = 0.0
        if tag and tag != '*' and q > 0:
            tags.append((-q, i, tag))
    return [tag for _, _, tag in sorted(tags)]


def best(wanted, offered) -> str | None:
    """The first wanted tag offered, exactly or by its base language ('es-ES' -> 'es')."""
    for raw in wanted:
        if not raw:
            continue
        tag = str(raw).strip().replace('_', '-').lower()
        if tag in offered:
            return tag
        if tag.split('-')[0] in offered:
            return tag.split('-')[0]
    return None


class Texts:
    """The translations in ``directory`` (read again when a file changes: a teacher's edit shows
    without a restart)."""

    def __init__(self, directory: Path):
        self.directory = Path(directory)
        self._cache: dict[str, tuple[float, dict]] = {}

    def _load(self, name: str) -> dict:
        path = self.directory / f'{name}.json'
        try:
            mtime = path.stat().st_mtime
        except OSError:
            return {}
        cached = self._cache.get(name)
        if cached and cached[0] == mtime:
            return cached[1]
        try:
            data = json.loads(path.read_text(encoding='utf-8'))
        except (OSError, ValueError) as e:
            log.warning('i18n: %s is unreadable: %s', path, e)
            data = {}
        data = data if isinstance(data, dict) else {}
        self._cache[name] = (mtime, data)
        return data

    def offered(self) -> list[str]:
        return list(self._load('languages')) or ['en']

    def pick(self, handler) -> str:
        """The language for a request: ?lang=, the menu's cookie, Accept-Language, else English."""
        wanted = [handler.get_argument('lang', None), handler.get_cookie(COOKIE)]
        wanted += accepted(handler.request.headers.get('Accept-Language', ''))
        return best(wanted, self.offered()) or 'en'

    def direction(self, lang: str) -> str:
        info = self._load('languages').get(lang)
        return info.get('dir', 'ltr') if isinstance(info, dict) else 'ltr'

    def get(self, lang: str, key: str, **values) -> str:
        """The text of ``key`` in ``lang`` (else English, else the key), placeholders filled."""
        text = self._load(lang).get(key) if lang != 'en' else None
        if not isinstance(text, str):
            text = self._load('en').get(key, key)
        for name, value in values.items():
            text = text.replace('{' + name + '}', str(value))
        return text
