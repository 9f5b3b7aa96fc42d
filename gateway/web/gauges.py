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

from pathlib import Path

import tornado.web

from ..rules.access import Action, Area, allowed
from ..twin.gauges import read_limits
from .api import JsonHandler, authorized


class GaugesHandler(JsonHandler):
    def initialize(self, path: Path | None) -> None:
        self.path = path

    @authorized(Area.GAUGES)
    def get(self) -> None:
        server = allowed(self.identity, Action.SEE, Area.SERVER)   # the server's paths are the admins'
        if self.path is None:
            self.finish({'limits': {}})
            return
        try:
            limits = read_limits(self.path)
        except (OSError, ValueError, RecursionError) as e:
            why = str(e) if server else str(e).replace(str(self.path), self.path.name)
            if not server and isinstance(e, OSError):
                why = f'{self.path.name}: {e.strerror or "cannot be read"}'   # the server's paths are the admins'
            raise tornado.web.HTTPError(500, f'the --gauges file: {why}') from None
        self.finish({'limits': limits})


def gauge_routes(path: Path | None) -> list:
    """``path``: the --gauges file (``Settings.twin.gauges``), or None."""
    return [(r'/api/gauges', GaugesHandler, {'path': Path(path).expanduser() if path else None})]
