"""The runs' start: the box (bubblewrap sandbox, cgroups, the box's home and the unix socket the runs
reach the gateway by) as ``--allow-runs`` and ``--trusted-runs`` ask, and the run manager given them
with its doors (``runs.ports``). A box that cannot be made refuses the start (``settings.Refused``).
"""

from __future__ import annotations

import logging
import os
import shutil
import socket
import sys
from collections.abc import Callable
from pathlib import Path

import tornado.netutil

from ..settings import Refused, Settings, data_dir
from ..store import Store
from .archive import Archive
from .cgroups import Cgroups, limits_in_force
from .ports import Announcer, Graph, InForce
from .process import RunLimits
from .sandbox import Sandbox, SandboxUnavailable, make_home, run_user
from .supervisor import RunManager

log = logging.getLogger('rosgate.runs')


def start_runs(settings: Settings, *, store: Store, announce: Announcer, graph: Graph,
               rules: Callable[[], InForce | None]) -> tuple[RunManager, socket.socket | None]:
    """The run manager as the settings ask, and the unix socket the boxes reach the gateway by
    (None: runs are off, or trusted runs reach the gateway's port themselves), for the server's
    start to serve (``RunManager.serve``). With --allow-runs and no working bwrap a Refused
    names what to install (the gateway does not start). store: the runs' archive; announce,
    graph, rules: the manager's doors (``runs.ports``)."""
    flags = settings.runs
    runs_dir = Path(flags.runs_dir or default_runs_dir())
    box = cgroups = home = sock = None
    if flags.allow_runs:
        private = [settings.storage.programs_dir, runs_dir, settings.storage.record, data_dir(''), settings.certfile,
                   settings.keyfile, Path.home(), *(a for a in sys.argv[1:] if a.startswith('/'))]
        home, home_lock = make_home()
        try:
            user = run_user()
            sock = None     # a trusted run, on the machine's network, reaches the gateway's port itself
            if not flags.trusted_runs:
                sock = tornado.netutil.bind_unix_socket(str(home / 'gateway.sock'), mode=0o600 if user is None else 0o660)
            if user is not None:     # the runs' user reaches the socket through its group (else it is ours)
                os.chown(home, 0, user[1])
                if sock is not None:
                    os.chown(home / 'gateway.sock', 0, user[1])
                home.chmod(0o750)
            box = Sandbox.create(private, home=home, socket=None if sock is None else str(home / 'gateway.sock'),
                                 graph=flags.trusted_runs)
        except SandboxUnavailable as e:
            shutil.rmtree(home, ignore_errors=True)
            os.close(home_lock)
            raise Refused('--allow-runs', str(e)) from None
        cgroups, how = Cgroups.find()
        if cgroups is not None:
            cgroups.sweep()
        if box.graph:
            log.warning('runs: --trusted-runs: each run is a node of the ROS graph itself; what it publishes '
                        'that way is outside every rule of this gateway (lease, globs, clamps, stops, slot '
                        'ends): only its websocket ops obey them')
        lim = RunLimits()
        log.info('runs: in a bwrap sandbox; %s', limits_in_force(
            cgroups, how, memory_mb=lim.memory_mb, processes=lim.processes, cpus=lim.cpus,
            cpu_seconds=lim.cpu_seconds, open_files=lim.open_files))
    archive = Archive(store, cap=flags.run_output_cap, keep_days=flags.runs_keep_days,
                      keep_count=flags.runs_keep_count, keep_bytes=flags.runs_keep_bytes,
                      keep_share=flags.runs_keep_share)
    manager = RunManager(settings, announce=announce, graph=graph, rules=rules, allowed=flags.allow_runs,
                         runs_dir=runs_dir, box=box, cgroups=cgroups, max_runs=flags.max_runs,
                         max_per_person=flags.max_runs_per_person, archive=archive,
                         home=home,                                        # removed at shutdown
                         home_lock=home_lock if flags.allow_runs else None)   # held while the gateway lives
    return manager, sock


def default_runs_dir() -> Path:
    return data_dir('runs')
