"""The robot's description and its meshes, for the 3D twin (``/twin``):

GET /package/PKG/PATH     a file of description package PKG: ``<prefix>/share/PKG/PATH`` for each
                          prefix of ``AMENT_PREFIX_PATH`` (the robot's installed packages), then
                          ``DIR/PKG/PATH`` for each ``--mesh-path DIR`` (a folder of packages). What
                          a URDF's ``package://PKG/PATH`` (and ``file://`` under those roots) names.
(``/urdf`` and ``/api/description``, the description itself: ``description``.)

Read-only, and only files under those roots: a path with ``..``, ``.``, an empty or hidden
segment (``.git``), a backslash or a NUL byte is refused (403) whatever its encoding (tornado
decodes ``%2e%2e`` and ``%2f`` before the check); a symlink whose target leaves its root is
refused (the real path is checked, not the spelled one) unless it lands under another root: with
colcon's ``--symlink-install`` a share folder's files are symlinks into the source tree, served when
that folder is given with ``--mesh-path`` (as docs/robot-builder.md says); only mesh, texture and description
files are served (``SUFFIXES``), so a package's scripts or config stay private. Cached by the
browser (ETag and Last-Modified from tornado's StaticFileHandler, revalidated after
``MAX_AGE``): a Husky's meshes are some 8 MB, which a page reload need not fetch again.
With --auth, a valid token is needed, as for the other reads (``api.authorized``).
"""

from __future__ import annotations

from pathlib import Path

import tornado.web

from ..twin.packages import find, package_roots
from ..rules.access import Area
from ..rules.errors import Refusal
from .api import authorized

MAX_AGE = 300   # s a mesh is used from the browser's cache before it is revalidated (304)


class PackageHandler(tornado.web.StaticFileHandler):
    """A file found by ``find``; tornado's static handler gives ETag, Last-Modified, 304 and ranges."""

    def initialize(self, roots: list[Path]) -> None:
        super().initialize(path='/')
        self.roots = roots

    @authorized(Area.PACKAGES)
    async def get(self, package: str, path: str, include_body: bool = True) -> None:
        try:
            real = find(self.roots, package, path)
        except Refusal as e:   # a static handler's errors are tornado's own
            raise tornado.web.HTTPError(e.status, e.message) from None
        if real is None:
            raise tornado.web.HTTPError(404, f'{package}/{path} is in no package root')
        self.root = str(real.parent)
        await super().get(real.name, include_body)

    def head(self, package: str, path: str):
        return self.get(package, path, include_body=False)

    def validate_absolute_path(self, root: str, absolute_path: str) -> str | None:
        return absolute_path   # find() has checked the real path

    def set_extra_headers(self, path: str) -> None:
        self.set_header('Cache-Control', f'private, max-age={MAX_AGE}')
        self.set_header('X-Content-Type-Options', 'nosniff')

    def get_content_type(self) -> str:
        suffix = Path(self.absolute_path).suffix.lower()
        if suffix in ('.urdf', '.xacro', '.xml', '.dae'):
            return 'text/xml; charset=utf-8'
        if suffix in ('.mtl', '.obj'):
            return 'text/plain; charset=utf-8'
        return super().get_content_type()


def package_routes(mesh_path: tuple) -> list:
    """``mesh_path``: the --mesh-path folders (``Settings.twin.mesh_path``)."""
    return [(r'/package/([^/]*)/(.*)', PackageHandler, {'roots': package_roots(mesh_path)})]
