"""/api/runs: robot-side runs over HTTP (``--allow-runs``); the runs themselves are ``gateway.runs``.

POST   /api/runs       {"source": "<python>", "name", "ns", "timeout"} or {"program": "<library name>", "owner", ...}
                       -> 201 {"id"}; 409 naming the run already going in that namespace
GET    /api/runs       -> {"allowed": bool, "runs": [summary, ...]}
GET    /api/runs/ID    -> {"id", "name", "ns", "state", "exit_code", "reason", "started", "ended", "output"}
DELETE /api/runs/ID    -> stops it: zero on every velocity topic it drove, SIGINT, SIGKILL after 2 s
"""

from __future__ import annotations

import re

import tornado.web

from ..rules.access import OPERATORS, owns
from ..rules.stations import person_of
from ..runs import Run, RunManager
from .api import JsonHandler, body_json, caller
from .programs import space_owner, stored_program

MAX_SOURCE = 1024 * 1024
NAMESPACE = re.compile(r'(/[A-Za-z_][A-Za-z0-9_]{0,63}){0,8}')   # ROS names, ASCII, a few levels


def _local_address(handler) -> tuple[str, int, bool]:
    """Where this request reached us (the run connects back the same way, on this machine)."""
    sock = handler.request.connection.stream.socket
    host, port = sock.getsockname()[:2]
    if host in ('0.0.0.0', '::'):
        host = '127.0.0.1'
    return host, port, handler.request.protocol == 'https'


def may_see(identity, run: Run) -> bool:
    """A run's state and output are its starter's and the admins' (everyone's with auth off)."""
    return owns(identity, identity is not None and run.owner == identity.owner)


class RunListHandler(JsonHandler):
    def initialize(self, manager: RunManager) -> None:
        self.manager = manager

    def get(self) -> None:
        identity = caller(self, self.manager.gateway)
        runs = [r.summary() for r in self.manager.runs.values() if may_see(identity, r)]
        self.finish({'allowed': self.manager.allowed, 'runs': runs})

    def post(self) -> None:
        m = self.manager
        if not m.allowed:
            raise tornado.web.HTTPError(403, 'runs are off on this gateway (start it with --allow-runs)')
        identity = caller(self, m.gateway, change=True, roles=OPERATORS)
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
        role = identity.role if identity is not None else None
        run = m.start(source, name, ns, float(timeout), role, _local_address(self),
                      person_of(identity, self.request.cookies))
        run.owner = identity.owner if identity is not None else None
        self.set_status(201)
        self.finish({'id': run.id, **run.summary()})

    def _library(self, name: str, identity, owner) -> str:
        """The Python stored with a library program, from the space the library would open for
        this caller: an operator's own (with --auth), else the shared one or an admin's "owner"."""
        programs_dir = self.manager.gateway.settings.storage.programs_dir
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


class RunHandler(JsonHandler):
    def initialize(self, manager: RunManager) -> None:
        self.manager = manager

    def _run(self, run_id: str) -> Run:
        run = self.manager.runs.get(run_id)
        if run is None:
            raise tornado.web.HTTPError(404, f'no run {run_id!r}')
        return run

    def get(self, run_id: str) -> None:
        identity = caller(self, self.manager.gateway)
        run = self._run(run_id)
        if not may_see(identity, run):
            raise tornado.web.HTTPError(403, f'run {run.id} was started by {run.owner or "someone else"}; its state '
                                             f'and output are for them and admins, not {identity.name}')
        self.finish(run.detail())

    def delete(self, run_id: str) -> None:
        identity = caller(self, self.manager.gateway, change=True, roles=OPERATORS)
        run = self._run(run_id)
        if not may_see(identity, run):
            raise tornado.web.HTTPError(403, f'run {run.id} was started by {run.owner or "someone else"}; '
                                             f'{identity.name} may not stop it')
        self.manager.stop(run)
        self.set_status(202 if run.ended is None else 200)
        self.finish(run.summary())


def run_routes(manager: RunManager) -> list:
    kw = {'manager': manager}
    return [(r'/api/runs/?', RunListHandler, kw), (r'/api/runs/(r[0-9a-f]{8})/?', RunHandler, kw),
            (r'/api/runs/([^/]+)', RunHandler, kw)]
