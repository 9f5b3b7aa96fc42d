"""The dashboard's gauge limits, set once per robot in a file (``--gauges FILE``, JSON or TOML):

GET /api/gauges   -> {"limits": {NAME: {"min", "max", "warn", "danger", "low"}, ...}} ({} without a file)

NAME is a topic, or a glob of topics (``/robot*/motor/*/temperature``); a name without a leading
``/`` is relative: the teleop page reads it under its own robot's namespace, so one entry serves
every robot of a fleet. A JointState topic's entry gives its joints' limits under ``effort`` and
``temperature`` (``{"effort": {"max": 40, "warn": 25, "danger": 35}}``). A gauge with no entry
takes its limits from its message (a BatteryState's percentage or charge over its design capacity)
or from the page's defaults. The file is read on each request (a few hundred bytes), so a
changed limit needs no restart; with --auth, a valid token is needed, as for the other reads.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import tornado.web

from ..rules.access import acts_as_admin
from .api import JsonHandler, caller

KEYS = frozenset({'min', 'max', 'warn', 'danger', 'low'})
PARTS = frozenset({'effort', 'temperature'})


def _check(name: str, entry, where: str) -> None:
    if not isinstance(entry, dict):
        raise ValueError(f'{where}: the entry of {name!r} is not a table of limits')
    for key, value in entry.items():
        if key in PARTS and not where.endswith(f'.{key}'):
            _check(name, value, f'{where}.{key}')
        elif key == 'low':
            if not isinstance(value, bool):
                raise ValueError(f'{where}: {name!r}: "low" is true or false')
        elif key in KEYS:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f'{where}: {name!r}: {key!r} is not a number')
        else:
            raise ValueError(f'{where}: {name!r}: unknown key {key!r} (one of {", ".join(sorted(KEYS | PARTS))})')


def read_limits(path: Path) -> dict:
    """The limits in a --gauges file; ValueError saying what is wrong with it."""
    text = Path(path).read_bytes()
    try:
        data = tomllib.loads(text.decode()) if Path(path).suffix == '.toml' else json.loads(text)
    except (ValueError, UnicodeDecodeError) as e:
        raise ValueError(f'{path}: {e}') from None
    if not isinstance(data, dict):
        raise ValueError(f'{path}: not a table of topic names')
    for name, entry in data.items():
        _check(name, entry, str(path))
    return data


class GaugesHandler(JsonHandler):
    def initialize(self, gateway, path: Path | None) -> None:
        self.gateway, self.path = gateway, path

    def get(self) -> None:
        identity = caller(self, self.gateway)
        if self.path is None:
            self.finish({'limits': {}})
            return
        try:
            limits = read_limits(self.path)
        except (OSError, ValueError, RecursionError) as e:
            why = str(e) if acts_as_admin(identity) else str(e).replace(str(self.path), self.path.name)
            if not acts_as_admin(identity) and isinstance(e, OSError):
                why = f'{self.path.name}: {e.strerror or "cannot be read"}'   # the server's paths are the admins'
            raise tornado.web.HTTPError(500, f'the --gauges file: {why}') from None
        self.finish({'limits': limits})


def gauge_routes(gateway) -> list:
    path = gateway.settings.twin.gauges
    return [(r'/api/gauges', GaugesHandler, {'gateway': gateway, 'path': Path(path).expanduser() if path else None})]
