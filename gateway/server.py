"""The server's start: the gateway, its parts and its HTTP server, on sockets the CLI bound.

``start(gateway, files)`` makes the parts in this order, each before what needs it: the runs (their
manager, sandbox and unix socket: ``runs.start_runs``), the rules composed with the runs' part at
the publish door and put in force (``rules.compose``, ``Gateway.install``), the recordings (and
``--record``'s recording), the history, the OPC UA twin; each given what it uses, nothing assigned
to it later, and then every part that follows the gateway's events sealed into its hooks, once
(``rules.hooks``). ``web.app.make_app`` then only builds the
route table from them; ``serve`` runs it all until SIGINT or SIGTERM and stops it in the reverse.
A part that cannot start as asked raises ``settings.Refused`` (the CLI exits 2 naming the flags).
"""

from __future__ import annotations

import asyncio
import logging
import signal
import socket
import ssl
from dataclasses import dataclass

import tornado.httpserver
import tornado.ioloop

from . import rules
from .lab import grades, roster
from .bridge import rosapi, topicstats
from .bridge.gateway import Gateway
from .bridge.outbox import BATCHING
from .bridge.taps import Senders, Taps
from .lab.checker import LiveAttempts
from .lab.exercises import Checker, Library
from .runs import RunManager, start_runs
from .settings import Settings
from .web.app import make_app, socket_app
from .twin.history import History, start_history
from .twin.opcua import start_twin
from .web.pages import ide_problem
from .media.recordings import RecordingManager, start_recordings

log = logging.getLogger('rosgate')


@dataclass(frozen=True)
class Parts:
    """What the route table serves, started."""
    runs: RunManager
    recordings: RecordingManager
    history: History | None
    lti: object = None        # auth.lti.LtiConfig with --lti
    grades: object = None     # lab.grades.Outbox with --lti: posts queued scores to the LMS
    exercises: Library | None = None
    checker: Checker | None = None   # the live exercise attempts (their ends told to the hooks)


def start(gateway: Gateway, files: rules.Files) -> Parts:
    settings = gateway.settings
    runs, runs_socket = start_runs(settings, store=gateway.store, announce=gateway, graph=gateway.backend,
                                   rules=lambda: gateway.ruleset)   # the rules, composed next, hold the runs
    attempts = LiveAttempts()   # the checker's live attempts, whose stations the rules keep
    reads = lambda name: rosapi.handles(name) or name == topicstats.SERVICE   # noqa: E731 (what viewers may call)
    ruled = rules.compose(gateway.rule_doors(), files, reads=reads, runs=runs, attempts=attempts.live,
                          keepers=(runs.keeper,))
    gateway.install(ruled)
    recordings = history = twin = outbox = None
    try:
        topicstats.TopicStats(gateway)   # /rosgate/topic_stats: the rates /inspect shows
        taps = Taps(gateway)   # the topics' shared fan-outs, for the parts that are not clients
        recordings = start_recordings(settings.storage, taps=taps, types=gateway.backend, graph=gateway.backend,
                                      senders=Senders(gateway), names=gateway.policy)
        if files.lti is not None:   # an ended attempt's score goes to the LMS of the learner's launch
            outbox = grades.Outbox(gateway.store, files.lti)
            outbox.start()
            if any(reg.memberships_urls for reg in files.lti.registrations):   # rosters known before any launch
                tornado.ioloop.IOLoop.current().spawn_callback(roster.refresh, gateway.store, files.lti)
        checker = Checker(gateway, gateway.store, attempts=attempts, recorder=recordings, events=gateway.hooks)
        history = start_history(settings.twin, gateway.hooks, store=gateway.store, taps=taps, graph=gateway.backend,
                                names=gateway.policy, fleet=gateway.ruleset.fleet)
        twin = start_twin(history, settings.twin.opcua, policy=gateway.policy, address=settings.address)
    finally:
        # every part built hears the gateway's events from now (and its shutdown, should a part fail to
        # start), in this order: the rules' first (a slot's end stops a station's commands before its
        # run is stopped), then the recordings, the history, the twin, the grades' outbox
        gateway.hooks.seal((*ruled.hooks, recordings, history, twin, outbox))
    if runs_socket is not None:   # runs reach the websocket alone, on a unix socket bound into their box
        runs.serve(socket_app(gateway), runs_socket)
    return Parts(runs=runs, recordings=recordings, history=history, lti=files.lti, grades=outbox,
                 exercises=Library(settings.lab.exercises_dir), checker=checker)


def pages_box(base: str) -> str:
    """The pages' addresses framed, after the start-up line: with --fleet 30 the line came after
    some 60 lines of log and a teacher did not find it. The line above stays one line for scripts."""
    rows = [('IDE (students)', base), ('teleop (driving)', f'{base}teleop'), ('twin (3D robot)', f'{base}twin'),
            ('class (teacher)', f'{base}class')]
    lines = ['rosgate is ready. Open in a browser:', *(f'  {name:<17} {url}' for name, url in rows)]
    if '//localhost:' in base:
        lines.append('  (other machines: this machine\'s address in place of localhost)')
    rule = '=' * max(len(line) for line in lines)
    return '\n'.join(['', rule, *lines, rule, ''])


async def serve(settings: Settings, files: rules.Files, backend, sockets: list[socket.socket], *,
                announce=print) -> None:
    """Run the gateway on sockets already bound (``tornado.netutil.bind_sockets``)."""
    await backend.start(**BATCHING)   # each client gets a batch's frames in one write (bridge.outbox)
    gateway = Gateway(settings, backend)
    try:
        parts = start(gateway, files)
    except BaseException:
        await gateway.shutdown()
        await backend.stop()
        raise
    app = make_app(gateway, parts)
    gateway.count_clients()
    ssl_ctx = None
    if settings.certfile and settings.keyfile:
        ssl_ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
        ssl_ctx.load_cert_chain(settings.certfile, settings.keyfile)
    server = tornado.httpserver.HTTPServer(app, ssl_options=ssl_ctx, max_buffer_size=settings.max_message_size * 4,
                                           body_timeout=settings.body_timeout,
                                           idle_connection_timeout=settings.idle_connection_timeout)
    server.add_sockets(sockets)
    port = sockets[0].getsockname()[1]
    host = settings.address if settings.address not in ('', '0.0.0.0', '::') else 'localhost'
    host = f'[{host}]' if ':' in host else host
    http, ws = ('https', 'wss') if ssl_ctx else ('http', 'ws')
    path = settings.url_path if settings.url_path.startswith('/') else '/' + settings.url_path
    problem = ide_problem(settings.ide_dir)
    base = f'{http}://{host}:{port}/'
    ide = (f'IDE {base} teleop {base}teleop twin {base}twin class {base}class' if problem is None
           else f'IDE unavailable ({problem})')
    announce(f'rosgate: {ide} websocket {ws}://{host}:{port}{path} backend {backend.name} '
             f'node {backend.node_name}')
    if problem is None:
        announce(pages_box(base))

    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    await stop.wait()
    log.info('shutting down')
    server.stop()
    if parts.checker is not None:
        parts.checker.stop_all()
    if parts.grades is not None:   # the stopped attempts' scores into the outbox before the store closes
        await parts.grades.stop()
    await gateway.shutdown()
    await backend.stop()
    await server.close_all_connections()
