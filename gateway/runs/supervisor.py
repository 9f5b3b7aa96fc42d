"""The run supervisor: starts a robot-side run's process in its box, follows it, stops it.

The process is a fresh interpreter (the gateway's, where roslibpy is installed) inside a
bubblewrap sandbox (``sandbox``: namespaces of its own, a read-only view of the interpreter, no
gateway process or file in sight; the whole tree dies with it), with a clean environment, a cgroup
where the machine allows one (``cgroups``), and resource limits set by the launcher (``launcher``)
right before it execs the program. The program connects back to the gateway as an ordinary
rosbridge client, with a per-run key in its URL: the gateway knows that connection as the run's,
so the safety layer can stop what it drove and the driver lease can be the run's. Each line of
its output is published on /rosgate/runs/ID/output (std_msgs/msg/String), and its state (a JSON
text) on /rosgate/runs/ID/state, latched.

At most ``--max-runs`` runs go at once, ``--max-runs-per-person`` of one signed-in person (an
admin has only the first limit), each in a namespace of the graph (a station like /s07, or the
root): a run's namespace is a name the gateway knows, not any text. A refusal is a ``RunError``
carrying its HTTP status (the web layer answers it).

The manager is given what it uses (``runs.ports``): the settings, the gateway's own topics
(``Announcer``), the graph's nodes (``Graph``), and the rules in force (``rules``: the driver lease, the
safety's stops, whether anyone signs in), read when a run needs them, since the rules are composed
after the manager (they hold its part at the publish door).
"""

from __future__ import annotations

import asyncio
import hmac
import json
import logging
import os
import re
import secrets
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import tornado.httpserver

from protocol.errors import ProtocolError

from ..backends.base import QoS
from ..rules.access import Action, Area, allowed, as_role, owns, person_of
from ..rules.errors import Refusal
from ..rules.hooks import Hook
from ..rules.safety import moving_command
from ..settings import RunSettings, Settings
from . import launcher, node
from .archive import Archive
from .cgroups import Cgroups, RunCgroup
from .ports import Announcer, Graph, InForce, LeaseView, Stops
from .process import Run, RunLimits, RunOutput
from .sandbox import HOME, SOCKET, Sandbox, exit_code, kill_box

log = logging.getLogger('rosgate.runs')
STRING = 'std_msgs/msg/String'
KEEP_ENDED = 50                # ended runs kept (with their directories) before the oldest goes
KILL_AFTER = 2.0               # s between SIGINT and SIGKILL
CGROUP_GONE = 5.0              # s to wait for a run's cgroup to empty before leaving it behind
RUN_TOPIC = re.compile(r'/rosgate/runs/(r[0-9a-f]{8})/(?:output|state)')
LAUNCHER = Path(launcher.__file__).read_text()   # handed to the box's interpreter as source (-c)


class RunError(Refusal):
    """A run refused or failed to start: ``status`` is the HTTP status that says why (404, 409, 429, 500)."""


class RunManager(Hook):
    def __init__(self, settings: Settings, *, announce: Announcer, graph: Graph,
                 rules: Callable[[], InForce | None], allowed: bool, runs_dir: Path | None,
                 limits: RunLimits = RunLimits(), box: Sandbox | None = None, cgroups: Cgroups | None = None,
                 max_runs: int = RunSettings.max_runs, max_per_person: int = RunSettings.max_runs_per_person,
                 archive: Archive | None = None, home: Path | None = None, home_lock: int | None = None):
        """announce: the runs' output and state topics; graph: the namespaces a run may have;
        rules: () -> the rules in force (None before they are); home: the box's files of the
        gateway's (the unix socket, staged views), removed at shutdown; home_lock: the descriptor
        whose flock keeps ``home`` this gateway's (``sandbox.make_home``)."""
        self.settings, self.announce, self.graph, self.rules = settings, announce, graph, rules
        self.allowed, self.limits = allowed, limits
        self.archive = archive
        self.runs_dir = runs_dir
        self.box, self.cgroups = box, cgroups
        self.max_runs, self.max_per_person = max_runs, max_per_person
        self.runs: dict[str, Run] = {}
        self.server: tornado.httpserver.HTTPServer | None = None
        self.home, self.home_lock = home, home_lock

    def serve(self, app, sock) -> None:
        """Serve ``app`` (the rosbridge websocket alone) on the unix socket that the boxes bind in:
        the runs' one way to the gateway."""
        settings = self.settings
        self.server = tornado.httpserver.HTTPServer(app, max_buffer_size=settings.max_message_size * 4,
                                                    idle_connection_timeout=settings.idle_connection_timeout)
        self.server.add_socket(sock)

    # --- starting -----------------------------------------------------------------------------

    def start(self, source: str, name: str, ns: str, timeout: float, role: str | None, port: tuple[str, int, bool],
              person: str | None = None, *, owner: str | None = None, who: str | None = None,
              kind: str = 'python', record_bytes: int = 0):
        """A new Run, its process being started; raises RunError 404 for a namespace the graph does
        not have, 409 when the namespace is busy or its lease is not the starter's, 429 past the
        limits on runs going at once, 507 when the archive could not keep it. person: who starts it
        (rules.stations.person_of), for whom the run drives; owner and who: the starter's key and
        name (None: auth off); kind: what the source is; record_bytes: what its recording may take."""
        self._known(ns)
        going = [r for r in self.runs.values() if r.state in ('starting', 'running')]
        busy = next((r for r in going if r.ns == ns), None)
        if busy is not None:
            where = f'namespace {ns}' if ns else 'the root namespace'
            raise RunError(409, f'run {busy.id} ({busy.name}) is already running in {where}; '
                                             f'stop it first (DELETE /api/runs/{busy.id})')
        if len(going) >= self.max_runs:
            raise RunError(429, f'{len(going)} runs are going, the most this gateway runs at once '
                                             '(--max-runs); wait for one to end or stop one')
        mine = [r for r in going if person is not None and r.person == person]
        if not allowed(as_role(role), Action.EXEMPT, Area.RUNS) and len(mine) >= self.max_per_person:
            raise RunError(429, f'{person} has {len(mine)} runs going ({", ".join(r.id for r in mine)}), '
                                             'the most one person may (--max-runs-per-person); stop one first')
        if self.archive is not None:
            self.archive.room(record_bytes, owner)
        run_id = 'r' + secrets.token_hex(4)
        person = person or f'run {run_id}'
        self._lease_free_for(person, role, ns)
        program = self._program(source, kind)
        workdir = self.runs_dir / run_id
        try:
            workdir.mkdir(parents=True, mode=0o700)
            (workdir / 'program.py').write_text(program)
        except OSError:     # the log says where (a path is the admins')
            log.exception('run %s: cannot prepare %s', run_id, workdir)
            raise RunError(500, 'cannot prepare the run directory (the gateway\'s log says why)') from None
        run = Run(run_id, name, ns, timeout, workdir)
        run.kind = kind
        run.role, run.person, run.owner, run.who = role, person, owner, who
        latched = QoS(depth=1, transient_local=True)
        run.state_pub = self.announce.own_topic(f'/rosgate/runs/{run_id}/state', STRING, latched)
        run.output_pub = self.announce.own_topic(f'/rosgate/runs/{run_id}/output', STRING, QoS(depth=100))
        self.runs[run_id] = run
        if self.archive is not None:
            self.archive.begin(run, source, kind)
        self._forget_old()
        self._announce(run)
        task = asyncio.ensure_future(self._supervise(run, port))
        task.add_done_callback(lambda t: t.cancelled() or t.exception() is None or log.error(
            'run %s: supervising it failed', run.id, exc_info=t.exception()))
        return run

    @property
    def nodes(self) -> bool:
        """Whether a run may be a ROS 2 node (``runs.node``): runs on the graph (--trusted-runs)."""
        return self.box is not None and bool(self.box.graph)

    def _program(self, source: str, kind: str) -> str:
        """What the run's program.py holds: the source, or for a ROS 2 node (``runs.node``) the
        node with the IDE's runtime; refused (400) where runs are not on the graph."""
        if kind != node.KIND:
            return source
        if self.box is None or not self.box.graph:
            raise RunError(400, 'a ROS 2 node joins the ROS graph itself: this gateway runs nodes only with '
                                '--trusted-runs; run the program as a script (kind "python") instead')
        try:
            return node.node_program(source)
        except ValueError as e:
            raise RunError(400, str(e)) from None

    def namespaces(self) -> set[str]:
        """The root and the namespaces of the graph's nodes (/s07 of /s07/turtlesim, and so on)."""
        known = {''}
        for node in self.graph.nodes():
            parts = node.strip('/').split('/')[:-1]
            known.update('/' + '/'.join(parts[:i]) for i in range(1, len(parts) + 1))
        return known

    def _known(self, ns: str) -> None:
        known = self.namespaces()
        if ns not in known:
            names = ', '.join(sorted(n for n in known if n)[:20]) or 'none but the root'
            raise RunError(404, f'no robot namespace {ns} on this gateway (namespaces: {names})')

    def _lease_free_for(self, person: str, role: str | None, ns: str) -> None:
        """With --exclusive-control a run takes its namespace's driver lease (from its starter's own
        page quietly, and gives it back when it ends): refuse at once a run that could not (another
        person's station or lease, or a stop that holds until Take)."""
        lease = self._lease()
        why = lease.run_refusal(person, role, ns) if lease is not None else None
        if why is not None:
            raise RunError(409, why)

    def _env(self, run: Run, url: str) -> dict:
        """Only what a Python program needs: none of the gateway's own environment (tokens, keys).
        bwrap hands it on as it is (the run key stays out of every command line)."""
        graph = dict(self.box.environment) if self.box is not None else {}   # --trusted-runs
        return {**graph, 'PATH': '/usr/bin:/bin', 'HOME': HOME, 'LANG': 'C.UTF-8', 'PYTHONUNBUFFERED': '1',
                'PYTHONDONTWRITEBYTECODE': '1', 'ROSBRIDGE_URL': url, 'ROSGATE_NS': run.ns,
                'ROSGATE_RUN': run.id}

    async def _supervise(self, run: Run, port: tuple[str, int, bool]) -> None:
        host, number, tls = port
        path = self.settings.url_path
        path = path if path.startswith('/') else '/' + path
        relayed = self.box is not None and self.box.socket is not None
        if relayed:     # the relay in the box, at the gateway's port number: ws://localhost:9090 works too
            host, tls = '127.0.0.1', False
        host = f'[{host}]' if ':' in host else host
        # the key goes in the environment, not argv: other users of the machine can read argv
        url = f"{'wss' if tls else 'ws'}://{host}:{number}{path}?run_key={run.key}&name=run-{run.id}"
        lim = self.limits
        limits = f'{lim.cpu_seconds},{lim.memory_mb * 2**20},{lim.open_files},{lim.processes}'
        command = [sys.executable, '-I', '-c', LAUNCHER, limits, str(number if relayed else 0), SOCKET, 'program.py']
        if run.kind == node.KIND:
            command += node.node_arguments(run.ns)
        elif run.ns:
            command += ['--ns', run.ns]
        if self.cgroups is not None:
            run.cgroup = self.cgroups.make(run.id, lim.memory_mb * 2**20, lim.processes, lim.cpus)
        loop = asyncio.get_running_loop()
        output = RunOutput(lambda line: self._line(run, line), lambda: self._limit_reached(run),
                         self.limits.output_bytes, loop)
        try:
            with self.box.launch(command, run.workdir / 'program.py') as (argv, fds):
                transport, _ = await loop.subprocess_exec(
                    lambda: output, *(run.cgroup.join(argv) if run.cgroup else argv), cwd='/', pass_fds=fds,
                    env=self._env(run, url), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT, start_new_session=True)
        except OSError as e:
            self._line(run, f'could not start the program: {e}\n', ours=True)
            self._ended(run, None, f'could not start: {e}')
            return
        run.pid = transport.get_pid()
        if run.ending:   # stopped while it was starting
            self._signal(run, signal.SIGINT)
            run.timers.append(loop.call_later(KILL_AFTER, self._signal, run, signal.SIGKILL))
        run.state = 'running'
        self._announce(run)
        run.timers.append(loop.call_later(run.timeout, self.stop, run, 'timed_out'))
        try:
            await output.exited                 # bwrap ended: its init, so every process of the box, is gone
            try:
                await asyncio.wait_for(asyncio.shield(output.eof), KILL_AFTER)
            except asyncio.TimeoutError:        # cannot be, unless the kernel is slow to empty the box
                self._line(run, '[output after the program ended is not shown]\n', ours=True)
        finally:
            code = exit_code(transport.get_returncode())
            transport.close()
            self._ended(run, code, None)

    def _line(self, run: Run, line: str, *, ours: bool = False) -> None:
        """One line of output (or, ``ours``, a note of the gateway's)."""
        if 'MemoryError' in line and not ours:
            run.memory_error = True
        run.keep(line)
        if self.archive is not None:
            self.archive.line(run.id, line)
        run.output_pub.publish({'data': line.rstrip('\n')})

    def _limit_reached(self, run: Run) -> None:
        self._line(run, f'[output limit of {self.limits.output_bytes} bytes reached: further output is dropped]\n',
                   ours=True)

    # --- ending -------------------------------------------------------------------------------

    def stop(self, run: Run, why: str = 'stopped') -> None:
        """Zero what the run drives at once, then SIGINT; SIGKILL if it is still there after 2 s."""
        if run.state not in ('starting', 'running') or run.ending:
            return
        run.ending = why
        if why == 'timed_out':
            self._line(run, f'[timeout of {run.timeout:g} s: stopping]\n', ours=True)
        self.halt(run)
        self._signal(run, signal.SIGINT)
        run.timers.append(asyncio.get_running_loop().call_later(KILL_AFTER, self._signal, run, signal.SIGKILL))

    def _safety(self) -> Stops | None:
        rules = self.rules()
        return rules.safety if rules is not None else None

    def _lease(self) -> LeaseView | None:
        rules = self.rules()
        return rules.lease if rules is not None else None

    def halt(self, run: Run) -> int:
        safety = self._safety()
        if safety is None:
            return 0
        return sum(safety.stop_session(s) for s in run.sessions)

    def _signal(self, run: Run, sig: int) -> None:
        """SIGINT to the program's process group; SIGKILL to the whole box."""
        if run.pid is not None and run.ended is None:
            kill_box(run.pid, sig)

    def _ended(self, run: Run, code: int | None, reason: str | None) -> None:
        for timer in run.timers:
            timer.cancel()
        run.timers.clear()
        run.exit_code, run.ended = code, time.time()
        if run.ending:
            run.state = run.ending
            if run.ending == 'timed_out':
                reason = f'timeout of {run.timeout:g} s'
        elif code == 0:
            run.state = 'finished'
        else:
            run.state = 'failed'
            reason = reason or self._why(run, code)
        run.reason = reason
        self._line(run, f'[run {run.state}{f": {reason}" if reason else ""}]\n', ours=True)
        if self.archive is not None:
            self.archive.end(run, self._recorded(run))
        self._announce(run)
        run.done.set_result(run.state)
        log.info('run %s (%s) %s%s', run.id, run.name, run.state, f': {reason}' if reason else '')
        if run.cgroup is not None:
            self._remove_cgroup(run.cgroup, time.monotonic() + CGROUP_GONE)

    @staticmethod
    def _recorded(run: Run) -> tuple[str, int] | None:
        """The run's recording finished now: (its file, its bytes), or None (not recorded, or it failed)."""
        if run.recorder is None:
            return None
        try:
            return run.recorder()
        except Exception:
            log.exception('run %s: its recording could not be finished', run.id)
            return None

    def _remove_cgroup(self, cgroup: RunCgroup, until: float) -> None:
        """A cgroup goes once the kernel has emptied it (its last processes may take a moment)."""
        if not cgroup.remove():
            if time.monotonic() < until:
                asyncio.get_running_loop().call_later(0.1, self._remove_cgroup, cgroup, until)
            else:
                log.warning('run cgroup %s still holds processes; left in place', cgroup.dirs[0])

    def _why(self, run: Run, code: int | None) -> str:
        if run.memory_error:
            return f'memory limit of {self.limits.memory_mb} MiB exceeded (MemoryError)'
        if run.cgroup is not None and run.cgroup.oom_killed():
            return f'memory limit of {self.limits.memory_mb} MiB exceeded (the kernel killed it)'
        if code is not None and code < 0:
            sig = signal.Signals(-code)
            if sig == signal.SIGXCPU:
                return f'CPU time limit of {self.limits.cpu_seconds} s exceeded'
            if sig in (signal.SIGKILL, signal.SIGSEGV):
                return f'killed by {sig.name} (perhaps the memory limit of {self.limits.memory_mb} MiB)'
            return f'killed by {sig.name}'
        return f'exit code {code}'

    def _announce(self, run: Run) -> None:
        run.state_pub.publish({'data': json.dumps(run.summary())})

    def _forget_old(self) -> None:
        ended = [r for r in self.runs.values() if r.ended is not None]
        for run in ended[:max(0, len(ended) - KEEP_ENDED)]:
            del self.runs[run.id]
            run.output_pub.destroy()
            run.state_pub.destroy()
            shutil.rmtree(run.workdir, ignore_errors=True)

    # --- gateway hooks ------------------------------------------------------------------------

    def on_connect(self, session, request) -> None:
        """A run's own connection (its key in the URL) becomes one of the run's sessions."""
        key = request.query_arguments.get('run_key')
        if not key:
            return
        key = key[-1].decode('ascii', 'replace')
        run = next((r for r in self.runs.values() if hmac.compare_digest(r.key, key)), None)
        if run is None or run.state not in ('starting', 'running'):
            return
        run.sessions.append(session)
        session.attrs.update(run=run.id, name=f'run {run.id}', person=run.person)
        if run.role is not None:
            session.attrs['role'] = run.role
            session.attrs.pop('auth_error', None)
        lease = self._lease()
        if lease is not None:
            try:
                lease.take(session, run.ns)
            except ProtocolError as e:
                self._line(run, f'[driver lease: {e.message}]\n', ours=True)

    def keeper(self, who, action: str, name: str) -> str | None:
        """A run's output and state topics are its starter's and the admins', as GET is: a keeper of
        ``rules.access``, so a recording or a stream is refused them as a subscription is."""
        found = RUN_TOPIC.fullmatch(name) if action == 'subscribe' else None
        run = self.runs.get(found.group(1)) if found else None
        rules = self.rules() if run is not None else None
        if rules is None or rules.policy.auth is None:
            return None
        attrs = getattr(who, 'attrs', {})
        mine = attrs.get('run') == run.id or (run.owner is not None and person_of(who) == run.person)
        if owns(who, mine):
            return None
        return (f'{name}: run {run.id} was started by {run.owner or "someone else"}; its output and state '
                'are for them and admins')

    def publish_hook(self, session, pub, msg, issued=None):
        """A run being stopped may still send commands before its SIGINT lands: those that would
        move the robot again are dropped."""
        run_id = session.attrs.get('run')
        if run_id is None:
            return msg
        run = self.runs.get(run_id)
        if run is not None and run.ending and moving_command(msg) and self._is_velocity(pub.type):
            return None
        return msg

    def _is_velocity(self, type: str) -> bool:
        safety = self._safety()
        return type in safety.types if safety is not None else type.startswith('geometry_msgs/msg/Twist')

    def on_slot_ended(self, station: str, person: str, why: str) -> None:
        """A booked slot ended (rules.bookings): the booker's runs in that station end."""
        for run in list(self.runs.values()):
            if run.person == person and (run.ns == station or run.ns.startswith(station + '/')):
                if run.state in ('starting', 'running') and not run.ending:
                    self._line(run, f'[{why}: stopping]\n', ours=True)
                    self.stop(run)

    def on_close(self, session) -> None:
        run = self.runs.get(session.attrs.get('run'))
        if run is not None and session in run.sessions:
            run.sessions.remove(session)

    async def on_shutdown(self) -> None:
        running = [r for r in self.runs.values() if r.pid is not None and r.ended is None]
        for run in running:
            self.stop(run)
        for run in running:
            try:
                await asyncio.wait_for(asyncio.shield(run.done), KILL_AFTER + 1)
            except asyncio.TimeoutError:
                self._signal(run, signal.SIGKILL)
        if self.server is not None:
            self.server.stop()
            await self.server.close_all_connections()
        if self.home is not None:
            shutil.rmtree(self.home, ignore_errors=True)
        if self.home_lock is not None:
            os.close(self.home_lock)
            self.home_lock = None
        if self.archive is not None:
            self.archive.close()
        left = [r.cgroup for r in self.runs.values() if r.cgroup is not None]
        deadline = time.monotonic() + 1.0
        while left and time.monotonic() < deadline:     # each goes once the kernel has emptied it
            left = [c for c in left if not c.remove()]
            if left:
                await asyncio.sleep(0.02)
