"""The robot's description over HTTP (``twin.description`` finds and expands it):

GET /api/description?ns=NS  -> {"urdf": TEXT, "from": "--urdf" | "topic" | "parameter"}
                               {"urdf": "", "from": null}: the robot has none (the twin then draws
                               a model by what the robot publishes)
GET /urdf                   the --urdf file (expanded when it is xacro; 404 without --urdf)
"""

from __future__ import annotations

import asyncio
import re
from pathlib import Path

import tornado.web

from ..settings import TwinSettings
from ..twin.description import Descriptions, XacroError
from ..twin.packages import package_roots
from .api import JsonHandler, authorized
from ..rules.access import Area

NAMESPACE = re.compile(r'(/[A-Za-z][A-Za-z0-9_]*)*')


class DescriptionHandler(JsonHandler):
    def initialize(self, descriptions: Descriptions) -> None:
        self.d = descriptions

    @authorized(Area.DESCRIPTION)
    async def get(self) -> None:
        who = self.identity
        ns = self.get_query_argument('ns', '').strip().rstrip('/')
        if ns and not ns.startswith('/'):
            ns = '/' + ns
        if not NAMESPACE.fullmatch(ns):
            raise tornado.web.HTTPError(400, f'"ns" is a robot namespace such as /s01, not {ns[:60]!r}')
        self.finish(await self.d.find(who, ns))


class UrdfHandler(tornado.web.RequestHandler):
    """GET /urdf: the --urdf file (expanded when xacro), for tools that fetch it."""

    def initialize(self, descriptions: Descriptions) -> None:
        self.d = descriptions

    @authorized(Area.DESCRIPTION)
    async def get(self) -> None:
        if self.d.urdf is None or not self.d.urdf.is_file():
            raise tornado.web.HTTPError(404, 'no --urdf given')
        try:
            text = await asyncio.to_thread(self.d.file_text)
        except (XacroError, OSError) as e:
            raise tornado.web.HTTPError(502, f'--urdf cannot be expanded: {e}') from None
        self.set_header('Content-Type', 'text/xml; charset=utf-8')
        self.set_header('Cache-Control', 'private, no-cache')
        self.set_header('X-Content-Type-Options', 'nosniff')
        self.finish(text)

    @authorized(Area.DESCRIPTION)
    async def head(self) -> None:
        if self.d.urdf is None or not self.d.urdf.is_file():
            raise tornado.web.HTTPError(404, 'no --urdf given')
        self.set_header('Content-Type', 'text/xml; charset=utf-8')


def description_files(twin: TwinSettings) -> tuple[Path | None, list[Path]]:
    """(the --urdf file, the package roots of --mesh-path) a ``Descriptions`` reads."""
    return Path(twin.urdf).expanduser() if twin.urdf else None, package_roots(twin.mesh_path)


def description_routes(descriptions: Descriptions) -> list:
    shared = {'descriptions': descriptions}
    return [(r'/api/description', DescriptionHandler, shared), (r'/urdf', UrdfHandler, shared)]
