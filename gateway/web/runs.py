"""/api/runs: robot-side runs over HTTP (``--allow-runs``); the runs themselves are ``gateway.runs``.

POST   /api/runs       {"source": "<python>", "name", "ns", "timeout"} or {"program": "<library name>", "owner", ...}
                       -> 201 {"id"}; 409 naming the run already going in that namespace
                       "kind": what the source is ("python" by default); "as": "operator" runs it with an
                       operator's rights, not the starter's higher ones; "record": true records the
                       station's topics (NS/*, or every topic in the root) for the run's length
GET    /api/runs       -> {"allowed": bool, "nodes": bool, "runs": [summary, ...]} (the runs of this gateway's
                           life; nodes: a run may be a ROS 2 node, kind "ros2_node", --trusted-runs)
GET    /api/runs?all=1 -> {"allowed", "runs": [kept run, ...]}: every kept run the caller may see, newest
                       first (an admin's: everyone's; ``person=NAME`` narrows it)
GET    /api/runs/ID    -> {"id", "name", "ns", "state", "exit_code", "reason", "started", "ended", "output"}
GET    /api/runs/ID/output, /source, /recording.mcap -> the kept output (text), source, recording
DELETE /api/runs/ID    -> stops it: zero on every velocity topic it drove, SIGINT, SIGKILL after 2 s
DELETE /api/runs?person=NAME -> an admin deletes every kept run of a person (their key or name)

A kept run (``runs.archive``) and its recording are its starter's and the admins', never anyone
else's (403), before a restart and after it.
"""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Protocol

import tornado.web

from ..lab.programs import stored_program
from ..rules.access import Action, Area, allowed
from ..rules.access import lowered
from ..rules.errors import Refusal
from ..rules.stations import person_of
from ..runs import Run, RunManager
from ..runs.archive import Archive
from .api import JsonHandler, authorize, authorized, body_json
from .programs import space_owner
from ..media.recordings import RecordingManager
from .recordings import send_file

MAX_SOURCE = 1024 * 1024
NAMESPACE = re.compile(r'(/[A-Za-z_][A-Za-z0-9_]{0,63}){0,8}')   # ROS names, ASCII, a few levels
KIND = re.compile(r'[a-z][a-z0-9_]{0,31}')
RECORD_SLACK = 5.0          # s a run's recording may outlast its timeout (it stops when the run ends)


class Graph(Protocol):
    """The backend's topics: what a run in the root namespace records."""
    def topics(self, hidden: bool = False) -> list[tuple[str, str]]: ...


def _local_address(handler) -> tuple[str, int, bool]:
    """Where this request reached us (the run connects back the same way, on this machine)."""
    sock = handler.request.connection.stream.socket
    host, port = sock.getsockname()[:2]
    if host in ('0.0.0.0', '::'):
        host = '127.0.0.1'
    return host, port, handler.request.protocol == 'https'


def may_see(identity, run: Run | dict) -> bool:
    """A run's state, output and recording are its starter's and the admins' (everyone's with auth off)."""
    owner = run['owner'] if isinstance(run, dict) else run.owner
    return allowed(identity, Action.SEE, Area.RUNS, owner)


def refuse(identity, run_id: str, who: str | None, what: str = 'its state and output are') -> None:
    raise tornado.web.HTTPError(403, f'run {run_id} was started by {who or "someone else"}; {what} '
                                     f'for them and admins, not {identity.name}')


def kept(row: dict) -> dict:
    """A kept run as GET /api/runs?all=1 lists it."""
    out = {k: row[k] for k in ('id', 'name', 'kind', 'ns', 'state', 'exit_code', 'reason', 'started', 'ended',
                               'output_bytes', 'output_seen', 'cut', 'recording_bytes')}
    return {**out, 'owner': row['who'], 'recorded': bool(row['recording'])}


class _Handler(JsonHandler):
    def initialize(self, manager: RunManager, recordings: RecordingManager, graph: Graph,
                   programs_dir: Path | None) -> None:
        self.manager, self.recordings, self.graph, self.programs_dir = manager, recordings, graph, programs_dir

    @property
    def archive(self) -> Archive:
        if self.manager.archive is None:
            raise tornado.web.HTTPError(404, 'runs are not kept on this gateway')
        return self.manager.archive

    async def row(self, run_id: str, identity, what: str) -> dict:
        """A kept run the caller may see (404, 403 else)."""
        row = await self.archive.store.run(lambda c: Archive.row(c, run_id))
        if row is None:
            raise tornado.web.HTTPError(404, f'no run {run_id!r}')
        if not may_see(identity, row):
            refuse(identity, run_id, row['who'], what)
        return row


class RunListHandler(_Handler):
    @authorized(Area.RUNS)
    async def get(self) -> None:
        identity = self.identity
        if self.get_argument('all', '') not in ('', '0'):
            everyone = allowed(identity, Action.MANAGE, Area.RUNS)
            owner = identity.owner if identity is not None else None
            rows = await self.archive.store.run(lambda c: Archive.rows(c, owner, everyone))
            person = self.get_argument('person', None)
            runs = [kept(r) for r in rows if person is None or person in (r['owner'], r['who'])]
        else:
            runs = [r.summary() for r in self.manager.runs.values() if may_see(identity, r)]
        self.finish({'allowed': self.manager.allowed, 'nodes': self.manager.allowed and self.manager.nodes, 'runs': runs})

    @authorized(Area.RUNS, Action.MANAGE)
    async def delete(self) -> None:
        """An admin deletes every kept run of a person (there is no other way a person leaves)."""
        identity = self.identity
        person = self.get_argument('person', '')
        if not person:
            raise tornado.web.HTTPError(400, 'give ?person=NAME: whose kept runs to delete')
        archive = self.archive
        gone = await archive.store.run(lambda c: archive.delete_person(c, person))
        self.finish({'deleted': gone, 'person': person, 'by': identity.name if identity is not None else None})

    def post(self) -> None:
        m = self.manager
        if not m.allowed:
            raise tornado.web.HTTPError(403, 'runs are off on this gateway (start it with --allow-runs)')
        identity = authorize(self, Area.RUNS)
        body = body_json(self, MAX_SOURCE)
        source = body.get('source')
        if source is None and body.get('program') is not None:
            source = self._library(str(body['program']), identity, body.get('owner'))
        if not isinstance(source, str) or not source.strip():
            raise tornado.web.HTTPError(400, 'give "source" (the Python program) or "program" (a library name)')
        name = body.get('name') or body.get('program') or 'program'
        if not isinstance(name, str) or len(name) > 64:
            raise tornado.web.HTTPError(400, '"name" is a text of at most 64 characters')
        ns = body.get('ns') or ''
        if isinstance(ns, str) and len(ns) <= 200:
            ns = '/' + '/'.join(p for p in ns.split('/') if p) if ns.strip('/') else ''
        if not isinstance(ns, str) or not NAMESPACE.fullmatch(ns):
            shown = repr(ns[:40]) + ('...' if len(ns) > 40 else '') if isinstance(ns, str) else repr(ns)
            raise tornado.web.HTTPError(400, f'"ns" is a robot namespace like /s07 (ASCII letters, digits and _), '
                                             f'not {shown}')
        timeout = body.get('timeout', m.limits.timeout)
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not 0 < timeout <= m.limits.max_timeout:
            raise tornado.web.HTTPError(400, f'"timeout" is a number of seconds, 0 < timeout <= {m.limits.max_timeout:g}')
        kind = body.get('kind', 'python')
        if not isinstance(kind, str) or not KIND.fullmatch(kind):
            raise tornado.web.HTTPError(400, '"kind" is a short lower-case word like "python"')
        record = body.get('record', False)
        if not isinstance(record, bool):
            raise tornado.web.HTTPError(400, '"record" is true or false')
        role = lowered(identity.role, body.get('as')) if identity is not None else None   # "as": "operator" lends less
        owner, who = (identity.owner, identity.name) if identity is not None else (None, None)
        run = m.start(source, name, ns, float(timeout), role, _local_address(self),
                      person_of(identity, self.request.cookies), owner=owner, who=who, kind=kind,
                      record_bytes=self.recordings.limits.max_bytes if record else 0)
        if record:
            self._record(run, owner)
        self.set_status(201)
        self.finish({'id': run.id, **run.summary()})

    def _record(self, run: Run, owner: str | None) -> None:
        """The station's topics recorded by the recorder of /api/recordings, under the starter's
        name, until the run ends (``Run.recorder`` finishes it). A recording refused (all slots
        taken, no room) stops the run at once: a run asked to be recorded is not run unrecorded."""
        recordings = self.recordings
        try:
            rec = recordings.start(self._station_globs(run.ns), run.timeout + RECORD_SLACK, owner)
        except Refusal as e:
            self.manager.stop(run, 'stopped')
            raise Refusal(e.status, f'run {run.id} stopped: its recording was refused: {e.message}') from None

        def finish() -> tuple[str, int]:
            recordings.stop(rec, f'run {run.id} ended')
            return str(rec.file), rec.bytes
        run.recorder = finish

    def _station_globs(self, ns: str) -> tuple[str, ...]:
        """NS/*; in the root, the graph's names but the gateway's own (/rosgate/...: other runs'
        output and state are not the starter's to record): /turtle1/* for /turtle1/pose, and so on."""
        if ns:
            return (f'{ns}/*',)
        names = [t for t, _ in self.graph.topics() if not t.startswith('/rosgate/')]
        return tuple(sorted({t if t.count('/') == 1 else f"/{t.split('/')[1]}/*" for t in names}))

    def _library(self, name: str, identity, owner) -> str:
        """The Python stored with a library program, from the space the library would open for
        this caller: an operator's own (with --auth), else the shared one or an admin's "owner"."""
        programs_dir = self.programs_dir
        owner = space_owner(identity, owner, 'run')
        if programs_dir is None or not (owner is None or isinstance(owner, str) and owner):
            raise tornado.web.HTTPError(400, f'no program library entry {name!r}')
        try:
            stored = stored_program(programs_dir, name, owner)
        except FileNotFoundError:
            raise tornado.web.HTTPError(404, f'no program named {name!r} in the library') from None
        except ValueError as e:
            raise tornado.web.HTTPError(400, str(e)) from None
        source = stored.get('python')
        if not isinstance(source, str):
            raise tornado.web.HTTPError(422, f'program {name!r} was saved without its Python; send "source"')
        return source


class RunHandler(_Handler):
    def _run(self, run_id: str) -> Run:
        run = self.manager.runs.get(run_id)
        if run is None:
            raise tornado.web.HTTPError(404, f'no run {run_id!r}')
        return run

    @authorized(Area.RUNS)
    async def get(self, run_id: str) -> None:
        identity = self.identity
        run = self.manager.runs.get(run_id)
        if run is None:     # a run of before the last restart, or one no longer in memory
            row = await self.row(run_id, identity, 'its state and output are')
            self.finish(kept(row))
            return
        if not may_see(identity, run):
            refuse(identity, run.id, run.who)
        self.finish(run.detail())

    @authorized(Area.RUNS)
    def delete(self, run_id: str) -> None:
        identity = self.identity
        run = self._run(run_id)
        if not may_see(identity, run):
            refuse(identity, run.id, run.who, 'stopping it is')
        self.manager.stop(run)
        self.set_status(202 if run.ended is None else 200)
        self.finish(run.summary())


class RunFileHandler(_Handler):
    """A kept run's output, source or recording, as a file to download."""

    @authorized(Area.RUNS)
    async def get(self, run_id: str, what: str) -> None:
        identity = self.identity
        row = await self.row(run_id, identity, 'its source, output and recording are')
        stamp = time.strftime('%Y%m%d-%H%M%S', time.localtime(row['started']))
        base = f"{re.sub(r'[^A-Za-z0-9_.-]+', '_', row['name'])}-{stamp}-{run_id}"
        if what == 'recording.mcap':
            await self._recording(row, base)
            return
        archive = self.archive
        if what == 'output':
            text = await archive.store.run(lambda c: Archive.output(c, run_id)) + archive.pending(run_id)
            kind, name = 'text/plain; charset=utf-8', f'{base}.txt'
        else:
            text, kind, name = row['source'], 'text/x-python; charset=utf-8', f'{base}.py'
        self.set_header('Content-Type', kind)
        self.set_header('Content-Disposition', f'attachment; filename="{name}"')
        self.finish(text.encode())

    async def _recording(self, row: dict, base: str) -> None:
        run = self.manager.runs.get(row['id'])
        if row['ended'] is None and run is not None and run.recorder is not None:
            raise tornado.web.HTTPError(409, f'run {row["id"]} is still going; its recording is there once it ends')
        path = Path(row['recording']) if row['recording'] else None
        if path is None:
            raise tornado.web.HTTPError(404, f'run {row["id"]} was not recorded (start it with "record": true)')
        if not path.is_file():
            raise tornado.web.HTTPError(404, f'the recording of run {row["id"]} was deleted')
        await send_file(self, path, f'{base}.mcap')


def run_routes(manager: RunManager, recordings: RecordingManager, graph: Graph, programs_dir: Path | None) -> list:
    """``graph``: the backend; ``programs_dir``: the program library (``Settings.storage.programs_dir``)."""
    kw = {'manager': manager, 'recordings': recordings, 'graph': graph, 'programs_dir': programs_dir}
    return [(r'/api/runs/?', RunListHandler, kw),
            (r'/api/runs/(r[0-9a-f]{8})/(output|source|recording\.mcap)', RunFileHandler, kw),
            (r'/api/runs/(r[0-9a-f]{8})/?', RunHandler, kw), (r'/api/runs/([^/]+)', RunHandler, kw)]
