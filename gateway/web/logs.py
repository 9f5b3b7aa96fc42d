"""What the process logs, made safe to read: no secrets and one line per record.

Tornado logs a request's URI on every 4xx and 5xx (and the access log on each request), and the
websocket takes its token as ``?token=`` (a run's connection, ``?run_key=``). A regex over the
name ``token`` missed ``?%74oken=`` and ``?to%6Ben=``, which tornado decodes to ``token`` before
it reads the value: so a URI's query is not logged at all, only its path (``/api/x?[query]``),
however its names are spelled. A ``name=value`` outside a query whose name, percent-decoded, is
a secret's is redacted as well (tornado quotes a bad request line's last word). Names clients
choose (run names, topics, labels) reach log messages too: a newline or other control character
in them is written escaped (``\\n``), so no text a client sends can start a log line of its own.
"""

from __future__ import annotations

import logging
import re
from urllib.parse import unquote

SECRET_PARAMS = ('token', 'run_key')
# a query: from '?' to the end of the word, when it holds a name=value (SQL's "(?, ?)" has none)
_QUERY = re.compile(r'\?[^\s\'"<>]*=[^\s\'"<>]*')
# a name=value pair; the name in any spelling (%74oken), judged once percent-decoded
_PAIR = re.compile(r'((?:[A-Za-z0-9_.~-]|%[0-9A-Fa-f]{2})+)=([^&\s#\'"]+)')
_CONTROL = re.compile(r'[\x00-\x08\x0a-\x1f\x7f\u0085\u2028\u2029]')


def _pair(match: re.Match) -> str:
    name = match.group(1)
    return f'{name}=[redacted]' if unquote(name).lower() in SECRET_PARAMS else match.group()


def _escape(match: re.Match) -> str:
    char = match.group()
    return {'\n': '\\n', '\r': '\\r'}.get(char, f'\\x{ord(char):02x}' if ord(char) < 0x100 else f'\\u{ord(char):04x}')


def scrub(text: str) -> str:
    """A log message with no URI query, secret values redacted and control characters escaped."""
    return _CONTROL.sub(_escape, _PAIR.sub(_pair, _QUERY.sub('?[query]', text)))


class Scrub(logging.Filter):
    """A handler filter: each record's message, formatted, goes through ``scrub`` (a traceback,
    added by the formatter afterwards, keeps its lines)."""

    def filter(self, record: logging.LogRecord) -> bool:
        try:
            message = record.getMessage()
        except Exception:   # a bad format: logging reports it itself
            return True
        clean = scrub(message)
        if clean != message or record.args:
            record.msg, record.args = clean, None
        return True


def install(logger: logging.Logger | None = None) -> None:
    """Put the filter on every handler of ``logger`` (the root logger)."""
    for handler in (logger or logging.getLogger()).handlers:
        handler.addFilter(Scrub())
