"""Robot-side runs: a program sent over HTTP runs as a process next to the robot (``--allow-runs``).

Rooms: ``supervisor`` (``RunManager``: starts a run's process, follows it, stops it; the run's
connection, its output topics and its part at the publish door), ``ports`` (what the manager is given:
the gateway's own topics, the graph, the rules in force, typed), ``boxes`` (``start_runs``: the box,
the runs' unix socket and the manager, made at the server's start), ``process`` (a run's record and its output pipe),
``sandbox`` (the bubblewrap box), ``cgroups`` (its memory, process and CPU limits where the machine
lets the gateway make cgroups), ``launcher`` (what runs in the box before the program: rlimits and
the relay to the gateway's socket). The HTTP routes are ``web.runs``; refusals are ``RunError``,
carrying their HTTP status.

May import: ``rules``, ``backends``, ``store`` and ``settings`` (and ``protocol``); never ``bridge`` or
``web``: the few doors the runs use are handed in (``ports``), never the Gateway.
"""

from .process import Run, RunLimits
from .boxes import start_runs
from .supervisor import RunError, RunManager

__all__ = ['Run', 'RunError', 'RunLimits', 'RunManager', 'start_runs']
