"""Reading the gateway's history over HTTP.

GET /api/history                          -> {"series": [{"topic", "fields": [...]}, ...]} (what the caller may read)
GET /api/history?topic=T&field=F&from=EPOCH&to=EPOCH[&step=S][&format=csv]
                                          -> {"topic", "field", "t": [...], "v": [...]}
                                             (+ "min", "max" per point when downsampled or per-minute)
GET /api/history/stats                    -> database size, rows written per second, topics kept

``from`` defaults to ten minutes before ``to``, ``to`` to now. Without ``step`` the points come
as kept: 1 Hz for the recent span, one per minute (its mean, with min and max) before that. With
``step`` (seconds) they are grouped into buckets of that length (t: the bucket's middle, v: the
mean, min and max). A span with no data gives empty arrays. A topic outside the history, or a
field it does not keep, gets 404 saying what it keeps; a bad number 400. Reading a topic's history
is subscribing to its past: the same name globs, roles and tokens apply as to a subscribe (403).
"""

from __future__ import annotations

import time

import orjson
import tornado.web

from ..rules.access import Action, Area, allowed, may
from ..rules.policy import Policy
from ..twin.history import History
from ..twin.queries import MAX_BUCKETS, figures, points, series
from .api import JsonHandler, authorized, query_number

DEFAULT_SPAN = 600.0
LATEST = 1e11        # s since 1970 (the year 5138): a larger from, to or step is no time the store can hold


class _Handler(JsonHandler):
    def initialize(self, history: History, policy: Policy) -> None:
        self.history, self.policy = history, policy

    def may_read(self, identity, topic: str) -> bool:
        """A read of a topic's past is a subscribe to it: the globs and the role decide."""
        self.refusal = may(self.policy, identity, 'subscribe', topic)
        return self.refusal is None


class HistoryHandler(_Handler):
    @authorized(Area.HISTORY)
    async def get(self) -> None:
        identity = self.identity
        topic = self.get_query_argument('topic', None)
        known = await series(self.history)
        if topic is None:
            self.finish({'series': [{'topic': t, 'fields': f} for t, f in sorted(known.items())
                                    if self.may_read(identity, t)]})
            return
        field = self.get_query_argument('field', None)
        if not field:
            raise tornado.web.HTTPError(400, 'give a field, e.g. &field=percentage')
        if not self.may_read(identity, topic):
            raise tornado.web.HTTPError(403, self.refusal)
        if topic not in known:
            kept = ', '.join(sorted(known)[:20]) or 'nothing yet'
            raise tornado.web.HTTPError(404, f'{topic[:200]} is not in the history (--history); it keeps {kept}')
        if field not in known[topic]:
            raise tornado.web.HTTPError(404, f'the history of {topic} has no field {field[:100]!r}; '
                                             f'it keeps {", ".join(known[topic]) or "no field yet"}')
        to = self.number('to', time.time())
        start = self.number('from', to - DEFAULT_SPAN)
        if start > to:
            raise tornado.web.HTTPError(400, f'"from" ({start:g}) is after "to" ({to:g})')
        step = self.get_query_argument('step', None)
        step_ms = None
        if step is not None:
            s = self.number('step', 0)
            if not s > 0:
                raise tornado.web.HTTPError(400, '"step" is a number of seconds above 0')
            if (to - start) / s > MAX_BUCKETS:
                raise tornado.web.HTTPError(400, f'"step" of {s:g} s gives more than {MAX_BUCKETS} points; take a longer one')
            step_ms = max(1, int(s * 1000))
        fmt = self.get_query_argument('format', 'json')
        if fmt not in ('json', 'csv'):
            raise tornado.web.HTTPError(400, '"format" is json or csv')
        lo, hi = int(start * 1000), int(to * 1000)
        data = await points(self.history, topic, field, lo, hi, step_ms, as_json=fmt == 'json')
        if fmt == 'csv':
            self.set_header('Content-Type', 'text/csv; charset=utf-8')
            self.set_header('Content-Disposition', f'attachment; filename="history.csv"')
            cols = ['t', 'v'] + [c for c in ('min', 'max') if c in data]
            self.write(','.join(cols) + '\n')
            self.finish(''.join(','.join(repr(data[c][i]) for c in cols) + '\n' for i in range(len(data['t']))))
            return
        self.finish(orjson.dumps({'topic': topic, 'field': field, 'from': start, 'to': to,
                                  **({'step': step_ms / 1000} if step_ms else {}), **data}))

    def number(self, name: str, default: float) -> float:
        return query_number(self, name, default, 'a number of seconds (since 1970 for from and to)',
                            low=0, high=LATEST)


class HistoryStatsHandler(_Handler):
    @authorized(Area.HISTORY)
    async def get(self) -> None:
        identity = self.identity
        stats = await figures(self.history)
        if not allowed(identity, Action.SEE, Area.SERVER):   # where the database is (a path, a host) is the admins'
            stats['db'] = stats['db'].split(':', 1)[0]
        self.finish(stats)


def history_routes(history: History | None, policy: Policy) -> list:
    if history is None:
        return [(r'/api/history(?:/stats)?', _Off)]
    kw = {'history': history, 'policy': policy}
    return [(r'/api/history/?', HistoryHandler, kw), (r'/api/history/stats', HistoryStatsHandler, kw)]


class _Off(JsonHandler):
    def get(self) -> None:
        raise tornado.web.HTTPError(404, 'this gateway keeps no history (started with --history none)')
