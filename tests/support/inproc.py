"""A gateway inside the test process, with no socket: the real ``Gateway`` on the sim backend with the
rules composed from the command line's flags (the CLI's parser and check, ``rules.compose``), and
clients that are real ``ClientSession``s fed frames as the websocket handler feeds them (its
``open``: the connection's attributes from the upgrade request, ``hooks.connect``), their replies
read back. For the rules' tables (tests/rules/test_rule_tables.py): a case costs microseconds
where a gateway process costs a second of CPU to start.

    async with InProcess('--fleet', '3', '--exclusive-control', '--auth', tokens) as gw:
        alice = gw.client(token='...')
        alice.send({'op': 'publish', 'topic': '/s01/turtle1/cmd_vel', 'msg': {...}})
        assert gw.lease.holders['/s01'] is alice.session
"""

from __future__ import annotations

import asyncio
import os
import tempfile

import orjson
import tornado.httputil

from gateway import rules
from gateway.bridge import rosapi
from gateway.bridge.gateway import Gateway
from gateway.bridge.outbox import BATCHING
from gateway.bridge.session import ClientSession
from gateway.cli import build_parser, check, make_backend, ros_style, settings_from
from gateway.rules.stations import BROWSER_COOKIE

from tests.support.wait import until


class InProcess:
    """The gateway of ``flags`` (as ``python -m gateway`` takes them; the sim backend, its store and
    data in a folder of its own), built on entering, shut down on leaving."""

    def __init__(self, *flags: str):
        self.home = tempfile.TemporaryDirectory(prefix='rosgate-inproc-')
        self.flags = ('--backend', 'sim', '--port', '0', '--db', f'sqlite:///{self.home.name}/rosgate.db', *flags)
        self.clients: list[Client] = []
        self._env = None

    async def __aenter__(self) -> InProcess:
        # the data directory (the cookie secret, runs, recordings) is read from the environment when used
        self._env = os.environ.get('XDG_DATA_HOME')
        os.environ['XDG_DATA_HOME'] = self.home.name
        parser = build_parser()
        settings = settings_from(parser.parse_args(ros_style(list(self.flags), parser)))
        start = check(settings)
        self.backend = make_backend(settings, start.robots, [], 'rosgate_in_process')
        await self.backend.start(**BATCHING)   # as server.serve starts it
        self.gateway = Gateway(settings, self.backend)
        # what viewers may call: the gateway's read-only services, as server.start gives them
        composed = rules.compose(self.gateway.rule_doors(), start.files, reads=rosapi.handles)
        self.gateway.install(composed)
        self.gateway.hooks.seal(composed.hooks)   # the rules' parts hear the gateway's events, as server.start seals them
        return self

    async def __aexit__(self, *exc) -> None:
        for c in self.clients:
            c.close()
        await self.gateway.shutdown()
        await self.backend.stop()
        if self._env is None:
            os.environ.pop('XDG_DATA_HOME', None)
        else:
            os.environ['XDG_DATA_HOME'] = self._env
        self.home.cleanup()

    @property
    def policy(self):
        return self.gateway.policy

    @property
    def lease(self):
        return self.gateway.ruleset.lease

    @property
    def stations(self):
        return self.gateway.ruleset.stations

    def client(self, token: str | None = None, *, name: str | None = None, browser: str | None = None,
               remote: str = '127.0.0.1') -> Client:
        """A client connecting as the websocket handler sees one: ``token`` as ?token=, ``name``
        as ?name=, ``browser`` as the browser's id cookie (who a person is with auth off)."""
        query = '&'.join(f'{k}={v}' for k, v in (('token', token), ('name', name)) if v is not None)
        headers = tornado.httputil.HTTPHeaders({'Host': 'localhost'})
        if browser is not None:
            headers['Cookie'] = f'{BROWSER_COOKIE}={browser}'
        start = tornado.httputil.RequestStartLine('GET', '/' + (f'?{query}' if query else ''), 'HTTP/1.1')
        request = tornado.httputil.HTTPServerRequest(start_line=start, headers=headers)
        c = Client(self.gateway, request, remote)
        self.clients.append(c)
        return c


class Client:
    """A ``ClientSession`` opened as ``gateway.web.socket`` opens one; ``sent``: what it was sent."""

    def __init__(self, gateway: Gateway, request, remote: str):
        self.sent: list[dict] = []
        self.closed_with: tuple[int, str] | None = None
        self.session = ClientSession(gateway, self._send, self._send_many, self._close, remote)
        self.session.attrs.update(gateway.policy.connect_attrs(request))
        self.session.open()
        gateway.hooks.connect(self.session, request)
        gateway.count_clients()

    def _send(self, payload: bytes, binary: bool):
        self.sent.append(orjson.loads(payload) if not binary else {'binary': payload})

    def _send_many(self, frames):
        for payload, binary in frames:
            self._send(payload, binary)

    def _close(self, code: int, reason: str) -> None:
        self.closed_with = (code, reason)

    def send(self, op: dict) -> None:
        """One text frame, as the websocket's reader hands it to the session."""
        self.session.receive(orjson.dumps(op).decode())

    def statuses(self, level: str | None = None) -> list[dict]:
        return [m for m in self.sent if m.get('op') == 'status' and (level is None or m.get('level') == level)]

    async def reply(self, id: str, timeout: float = 10) -> dict:
        """The first message that answers op ``id`` (its status, service response, result)."""
        return await until(lambda: next((m for m in self.sent if m.get('id') == id), None), timeout,
                           what=f'a reply to {id}')

    def close(self) -> None:
        if not self.session.closed:
            self.session.close()


async def settle() -> None:
    """The loop's callbacks already due have run (what one op scheduled: an outbox write, a hop)."""
    for _ in range(3):
        await asyncio.sleep(0)
