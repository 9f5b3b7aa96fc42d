"""Where the IDE pages and the example programs are.

An installed wheel (or a colcon install) carries them as package data in ``gateway/_assets/``
(copied there by setup.py at build time); a checkout, and an editable install of it, serves the
checkout's own ``ide/`` and ``examples/``, so a developer's edits show on reload.

What the gateway stores (programs, runs, recordings) goes under the user's XDG data directory.
"""

from __future__ import annotations

import os
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
PACKAGED = PACKAGE / '_assets'        # in a wheel
CHECKOUT = PACKAGE.parent             # the repository root, beside gateway/

# What the pages cannot work without (the bundles come from `npm run build` in ide/).
IDE_REQUIRED = ('index.html', 'teleop.html', 'vendor/roslib.mjs', 'vendor/blockly/blockly_compressed.js')


def _locate(name: str) -> Path:
    for base in (PACKAGED, CHECKOUT):
        if (base / name).is_dir():
            return base / name
    return PACKAGED / name


def ide_dir() -> Path:
    """The directory served at ``/`` (index.html, teleop.html, js/, css/, vendor/, ...)."""
    return _locate('ide')


def examples_dir() -> Path:
    """The example programs served at ``/examples/``."""
    return _locate('examples')


def ide_problem(ide: Path) -> str | None:
    """None when the pages can be served from `ide`, else a sentence saying what is missing."""
    missing = [f for f in IDE_REQUIRED if not (ide / f).is_file()]
    if not missing:
        return None
    if not (ide / 'index.html').is_file():
        return f'no IDE pages in {ide}'
    return (f'the IDE in {ide} is not built (missing {", ".join(missing)}): '
            'run `make ide` (npm ci && npm run build in ide/)')


def data_dir(name: str) -> Path:
    """``$XDG_DATA_HOME/rosgate/NAME`` (``~/.local/share/rosgate/NAME`` when unset)."""
    base = os.environ.get('XDG_DATA_HOME') or os.path.join(os.path.expanduser('~'), '.local', 'share')
    return Path(base) / 'rosgate' / name
