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
With --auth, a valid token is needed, as for the other reads (``api.caller``).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import tornado.web

from .api import caller

PACKAGE_NAME = re.compile(r'^[A-Za-z0-9_][A-Za-z0-9_-]{0,99}$')   # REP 144: letters, digits, _ (and - seen)
SUFFIXES = frozenset({'.stl', '.dae', '.obj', '.mtl', '.png', '.jpg', '.jpeg', '.tga', '.bmp', '.tif', '.tiff',
                      '.gltf', '.glb', '.bin', '.urdf', '.xacro', '.xml'})
MAX_AGE = 300   # s a mesh is used from the browser's cache before it is revalidated (304)


def package_roots(mesh_path=(), environ=os.environ) -> list[Path]:
    """The folders holding packages, in the order they are searched: the ``share`` folder of each
    ``AMENT_PREFIX_PATH`` prefix (as ament_index finds a package), then each ``--mesh-path``."""
    prefixes = [p for p in environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    return [Path(p) / 'share' for p in prefixes] + [Path(p) for p in mesh_path]


def safe_parts(path: str) -> list[str] | None:
    """The segments of a relative file path, or None for one that could leave its root."""
    if not path or '\\' in path or '\0' in path or path.startswith('/'):
        return None
    parts = path.split('/')
    if any(not p or p.startswith('.') or p != p.strip() for p in parts):
        return None
    return parts


def find(roots: list[Path], package: str, path: str) -> Path | None:
    """The real path of PACKAGE/PATH under the first root that has it, or None. Raises 403 for a
    name that could leave its root (checked again on the real path: symlinks)."""
    parts = safe_parts(path)
    if not PACKAGE_NAME.match(package) or parts is None:
        raise tornado.web.HTTPError(403, 'not a file of a package')
    if Path(parts[-1]).suffix.lower() not in SUFFIXES:
        raise tornado.web.HTTPError(403, f'only {", ".join(sorted(SUFFIXES))} files are served')
    left = False
    for root in roots:
        base = root / package
        candidate = base.joinpath(*parts)
        if not candidate.is_file():
            continue
        real = os.path.realpath(candidate)
        if not any(_under(real, os.path.realpath(r)) for r in (base, *roots)):
            left = True          # perhaps another root has it (a symlink-install's source folder)
            continue
        return Path(real)
    if left:
        raise tornado.web.HTTPError(403, 'the file leaves its package (give its real folder with --mesh-path)')
    return None


def _under(path: str, folder: str) -> bool:
    return os.path.commonpath([path, folder]) == folder


class PackageHandler(tornado.web.StaticFileHandler):
    """A file found by ``find``; tornado's static handler gives ETag, Last-Modified, 304 and ranges."""

    def initialize(self, gateway, roots: list[Path]) -> None:
        super().initialize(path='/')
        self.gateway, self.roots = gateway, roots

    async def get(self, package: str, path: str, include_body: bool = True) -> None:
        caller(self, self.gateway)
        real = find(self.roots, package, path)
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


def package_routes(gateway) -> list:
    roots = package_roots(gateway.settings.twin.mesh_path)
    return [(r'/package/([^/]*)/(.*)', PackageHandler, {'gateway': gateway, 'roots': roots})]
