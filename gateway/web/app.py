"""The tornado application: every route in one place.

``/`` upgrades to the rosbridge websocket (``socket``) and, as a plain GET, serves the IDE;
``/teleop``, ``/twin`` (the robot in 3D), ``/inspect`` (topics, nodes, log, parameters) and ``/class`` are the other pages; ``/health``; the JSON
API apps (``/api/programs``, ``/api/runs``, ``/api/recordings``, ``/api/history``, ``/api/bookings``),
the login pages and LTI's (``/lti/...``, with ``--lti``);
web_video_server's camera URLs (``/stream``, ``/snapshot``, ``/stream_viewer``, ``/streams``: ``video``);
the robot's meshes (``/package/PKG/PATH``: ``packages``) and description (``/api/description``, ``/urdf``:
``description``, xacro expanded); the gauges' limits
(``/api/gauges``: ``gauges``); block sets and the class's shared blocks (``/api/blocks``: ``blocksets``); exercises, their attempts and results (``/api/exercises``,
``/api/attempts``, ``/api/exercise-results``: ``exercises``); the LMS courses' roster (``/api/roster``: ``roster``);
the IDE's static files last. The parts behind the routes (runs, recordings, history, the OPC UA
server) are started by the server's start (``gateway.server``), not here.
"""

from __future__ import annotations

import math
import time

import orjson
import tornado.web

from ..bridge.gateway import Gateway
from ..bridge.taps import Taps
from ..media.video import Video
from ..twin.description import Descriptions
from .bookings import booking_routes
from .classview import ClassHandler
from .blocksets import block_routes
from .exercises import exercise_routes
from .gauges import gauge_routes
from .history import history_routes
from .language import Texts
from .packages import package_routes
from .description import description_files, description_routes
from .login import login_routes
from .lti_setup import lti_routes
from .roster import roster_routes
from .pages import Application, PublicFileHandler, write_page
from .programs import program_routes
from .recordings import recording_routes
from .runs import run_routes
from .share import share_routes
from .socket import RosbridgeHandler
from .video import video_routes

HARD_LIMIT_FACTOR = 4   # frames up to this many times max_message_size get a status; larger ones close 1009


class HealthHandler(tornado.web.RequestHandler):
    def initialize(self, gateway: Gateway) -> None:
        self.gateway = gateway

    def get(self) -> None:
        gw = self.gateway
        self.set_header('Content-Type', 'application/json')
        self.write(orjson.dumps({
            'status': 'ok', 'backend': gw.backend.name, 'clients': len(gw.sessions),
            'uptime': round(time.time() - gw.started, 3), 'topics': len(gw.fanouts),
            'images_rendered': gw.images_rendered,
            **_fleet(gw),
        }))


def _fleet(gw) -> dict:
    """In a fleet of gateways: this one's id, whether it keeps time, since when its database is away."""
    fleet = getattr(gw.ruleset, 'fleet', None)
    if fleet is None:
        return {}
    return {'fleet': {'gateway': fleet.id, 'timekeeper': fleet.timekeeper, 'unreachable': fleet.unreachable}}


class TeleopHandler(tornado.web.RequestHandler):
    """GET /teleop, /twin, /inspect: a page whose relative asset paths resolve from the root."""

    def initialize(self, page) -> None:
        self.page = page

    def get(self) -> None:
        write_page(self, self.page)


class IdeFileHandler(tornado.web.StaticFileHandler):
    """The static IDE; vendored files may change between installs, so revalidate them."""

    def set_extra_headers(self, path: str) -> None:
        self.set_header('Cache-Control', 'no-cache')


def options(settings) -> dict:
    return {'websocket_max_message_size': settings.max_message_size * HARD_LIMIT_FACTOR,
            'websocket_ping_interval': settings.websocket_ping_interval or None,
            # at most the interval: tornado cuts a longer one itself, with a warning at every start (cli.check says it once)
            'websocket_ping_timeout': min(settings.websocket_ping_timeout, settings.websocket_ping_interval or math.inf)}


def websocket_route(gateway: Gateway) -> tuple:
    ws_path = gateway.settings.url_path.rstrip('/') or '/'
    return (ws_path if ws_path == '/' else ws_path + '/?', RosbridgeHandler, {'gateway': gateway})


def socket_app(gateway: Gateway) -> tornado.web.Application:
    """The websocket alone: what the runs reach on their unix socket."""
    return Application(gateway.policy, [websocket_route(gateway)], **options(gateway.settings))


def make_app(gateway: Gateway, parts) -> tornado.web.Application:
    """The route table over the parts the server started (``server.start``); it starts nothing. Each
    route is handed what its handlers use, never the Gateway (the websocket's and /health's aside)."""
    settings, policy, store, ruleset = gateway.settings, gateway.policy, gateway.store, gateway.ruleset
    routes: list = [websocket_route(gateway)]
    routes += [
        (r'/health', HealthHandler, {'gateway': gateway}),
        (r'/teleop/', tornado.web.RedirectHandler, {'url': '/teleop'}),
        (r'/teleop', TeleopHandler, {'page': settings.ide_dir / 'teleop.html'}),
        (r'/twin/', tornado.web.RedirectHandler, {'url': '/twin'}),
        (r'/twin', TeleopHandler, {'page': settings.ide_dir / 'twin.html'}),
        (r'/inspect/', tornado.web.RedirectHandler, {'url': '/inspect'}),
        (r'/inspect', TeleopHandler, {'page': settings.ide_dir / 'inspect.html'}),
        (r'/class/?', ClassHandler, {'page': settings.ide_dir / 'class.html'}),
        (r'/examples/(.*)', IdeFileHandler, {'path': str(settings.examples_dir)}),
    ]
    texts = Texts(settings.ide_dir / 'i18n')    # the login and LTI pages' words, in the reader's language
    routes += login_routes(policy, texts)
    if parts.lti is not None:
        routes += lti_routes(parts.lti, policy, settings.examples_dir, texts, store, parts.exercises)
    routes += roster_routes(store, parts.lti)
    if settings.storage.programs_dir is not None:
        routes += program_routes(settings.storage.programs_dir, policy)
    routes += run_routes(parts.runs, parts.recordings, gateway.backend, settings.storage.programs_dir)
    routes += recording_routes(parts.recordings)
    routes += booking_routes(ruleset.slots, policy.sessions, store)
    taps = Taps(gateway)   # the topics' shared fan-outs, as a stream and a description read them
    routes += video_routes(Video(taps, gateway.backend), policy, gateway.backend)
    routes += history_routes(parts.history, policy)
    routes += package_routes(settings.twin.mesh_path) + gauge_routes(settings.twin.gauges)
    routes += block_routes(settings.storage.blocks_dir, settings.ide_dir)
    routes += description_routes(Descriptions(*description_files(settings.twin), taps=taps, graph=gateway.backend,
                                              names=policy))
    routes += share_routes(policy.auth is not None)
    if parts.checker is not None:
        routes += exercise_routes(parts.exercises, parts.checker, ruleset.attempts, store)
    routes.append((r'/(.*)', PublicFileHandler, {'path': str(settings.ide_dir), 'default_filename': 'index.html'}))
    return Application(policy, routes, compress_response=True, **options(settings))
