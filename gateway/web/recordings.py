"""The recordings over HTTP (``media.recordings`` is the domain: what is recorded and played, as whom):

POST   /api/recordings              {"topics": ["/turtle1/pose", "/scan*"], "max_seconds": 600} -> 201 {"id", ...}
GET    /api/recordings              -> {"recordings": [summary, ...]}: the caller's (an admin's: everyone's)
GET    /api/recordings/ID           -> summary (its starter's and the admins')
DELETE /api/recordings/ID           -> stops a recording (a finished one: deletes it); an exercise
                                       attempt's: an admin's alone (the teacher's evidence)
GET    /api/recordings/ID.mcap      -> the MCAP file (once it is finished)
POST   /api/recordings/ID/play      {"rate": 1.0, "prefix": "/replay"} -> 202; republishes with the original timing
DELETE /api/recordings/ID/play      -> stops playing
"""

from __future__ import annotations

import re
from pathlib import Path

import tornado.web

from ..rules.access import Action, Area, allowed
from ..rules.stations import person_of
from .api import JsonHandler, authorized, body_json
from ..media.recordings import RecordingManager


class _Handler(JsonHandler):
    def initialize(self, manager: RecordingManager) -> None:
        self.manager = manager


class RecordingListHandler(_Handler):
    @authorized(Area.RECORDINGS)
    def get(self) -> None:
        identity = self.identity
        self.finish({'recordings': self.manager.listing(identity, allowed(identity, Action.MANAGE, Area.RECORDINGS)),
                     'max_concurrent': self.manager.limits.max_concurrent})

    @authorized(Area.RECORDINGS)
    def post(self) -> None:
        m, identity = self.manager, self.identity
        body = body_json(self, 64 * 1024)
        topics = body.get('topics')
        if not isinstance(topics, list) or not topics or not all(isinstance(t, str) and t.startswith('/') for t in topics):
            raise tornado.web.HTTPError(400, '"topics" is a list of topic names or globs, like ["/turtle1/pose"]')
        seconds = body.get('max_seconds', m.limits.default_seconds)
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not 0 < seconds <= m.limits.max_seconds:
            raise tornado.web.HTTPError(400, f'"max_seconds" is a number, 0 < max_seconds <= {m.limits.max_seconds:g}')
        rec = m.start(tuple(topics), float(seconds), identity.owner if identity is not None else None, who=identity)
        self.set_status(201)
        self.finish(rec.summary())


class RecordingHandler(_Handler):
    @authorized(Area.RECORDINGS)
    def get(self, rec_id: str) -> None:
        identity = self.identity
        self.manager.check_owner(rec_id, identity, 'read')
        rec = self.manager.recordings.get(rec_id)
        if rec is not None:
            self.finish({**rec.summary(), 'playing': self.manager.is_playing(rec_id)})
            return
        self.manager.path(rec_id)
        self.finish(next(r for r in self.manager.listing() if r['id'] == rec_id))

    @authorized(Area.RECORDINGS)
    def delete(self, rec_id: str) -> None:
        m, identity = self.manager, self.identity
        m.check_owner(rec_id, identity, 'stop or delete', changes=True)
        rec = m.recordings.get(rec_id)
        if rec is not None and rec.state == 'recording':
            m.stop(rec, 'stopped')
            self.finish(rec.summary())
            return
        m.delete(rec_id)
        self.set_status(204)
        self.clear_header('Content-Type')
        self.finish()


class RecordingFileHandler(_Handler):
    @authorized(Area.RECORDINGS)
    async def get(self, rec_id: str) -> None:
        identity = self.identity
        file = self.manager.path(rec_id) / f'{rec_id}.mcap'
        self.manager.check_owner(rec_id, identity, 'download')
        await send_file(self, file, f'{rec_id}.mcap')


async def send_file(handler: tornado.web.RequestHandler, file: Path, name: str) -> None:
    """A recording's MCAP as a download named ``name``, a quarter MiB at a time."""
    handler.set_header('Content-Type', 'application/octet-stream')
    handler.set_header('Content-Disposition', f'attachment; filename="{name}"')
    handler.set_header('Content-Length', str(file.stat().st_size))
    with open(file, 'rb') as f:
        while chunk := f.read(256 * 1024):
            handler.write(chunk)
            await handler.flush()
    handler.finish()


class PlayHandler(_Handler):
    @authorized(Area.RECORDINGS)
    def post(self, rec_id: str) -> None:
        m, identity = self.manager, self.identity
        m.check_owner(rec_id, identity, 'play')
        body = body_json(self, 4096) if self.request.body else {}
        rate = body.get('rate', 1.0)
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0.01 <= rate <= 100:
            raise tornado.web.HTTPError(400, '"rate" is a number from 0.01 to 100')
        prefix = body.get('prefix') or ''
        if not isinstance(prefix, str) or (prefix and not re.fullmatch(r'(/[A-Za-z][A-Za-z0-9_]*)+', prefix)):
            raise tornado.web.HTTPError(400, '"prefix" is a namespace like /replay')
        self.set_status(202)
        self.finish(m.play(rec_id, float(rate), prefix, identity, person_of(identity, self.request.cookies)))

    @authorized(Area.RECORDINGS)
    def delete(self, rec_id: str) -> None:
        m, identity = self.manager, self.identity
        player = m.player(rec_id)
        if player is not None and not allowed(identity, Action.CHANGE, Area.RECORDINGS, player):
            raise tornado.web.HTTPError(403, f'{player} plays {rec_id}; {identity.name} may not stop it')
        self.finish({'stopped': m.stop_playing(rec_id)})


def recording_routes(manager: RecordingManager) -> list:
    """The /api/recordings routes."""
    kw = {'manager': manager}
    return [(r'/api/recordings/?', RecordingListHandler, kw),
            (r'/api/recordings/([^/]+)\.mcap', RecordingFileHandler, kw),
            (r'/api/recordings/([^/]+)/play', PlayHandler, kw),
            (r'/api/recordings/([^/.]+)', RecordingHandler, kw)]
