"""The robot's description packages on disk, for ``/package/`` (``web.packages``) and xacro's
``$(find PKG)`` (``description``): the package roots in the order they are searched, and the one
check that a file named by a URL stays under them (see ``web.packages`` for what is served).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from ..rules.errors import Refusal

PACKAGE_NAME = re.compile(r'^[A-Za-z0-9_][A-Za-z0-9_-]{0,99}$')   # REP 144: letters, digits, _ (and - seen)
SUFFIXES = frozenset({'.stl', '.dae', '.obj', '.mtl', '.png', '.jpg', '.jpeg', '.tga', '.bmp', '.tif', '.tiff',
                      '.gltf', '.glb', '.bin', '.urdf', '.xacro', '.xml'})


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
        raise Refusal(403, 'not a file of a package')
    if Path(parts[-1]).suffix.lower() not in SUFFIXES:
        raise Refusal(403, f'only {", ".join(sorted(SUFFIXES))} files are served')
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
        raise Refusal(403, 'the file leaves its package (give its real folder with --mesh-path)')
    return None


def _under(path: str, folder: str) -> bool:
    return os.path.commonpath([path, folder]) == folder
