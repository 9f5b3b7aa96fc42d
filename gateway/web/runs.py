"""Robot-side runs: a program sent over HTTP runs as a process next to the robot (``--allow-runs``).

POST   /api/runs       {"source": "<python>", "name", "ns", "timeout"} or {"program": "<library name>", "owner", ...}
                       -> 201 {"id"}; 409 naming the run already going in that namespace
GET    /api/runs       -> {"allowed": bool, "runs": [summary, ...]}
GET    /api/runs/ID    -> {"id", "name", "ns", "state", "exit_code", "reason", "started", "ended", "output"}
DELETE /api/runs/ID    -> stops it: zero on every velocity topic it drove, SIGINT, SIGKILL after 2 s

The process is a fresh interpreter (the gateway's, where roslibpy is installed) inside a
bubblewrap sandbox (sandbox.py: namespaces of its own, a read-only view of the interpreter, no
gateway process or file in sight; the whole tree dies with it), with a clean environment, a cgroup
where the machine allows one, and resource limits set by a tiny launcher right before it execs the
program. The program connects back to the gateway as an ordinary rosbridge client, with a per-run
key in its URL: the gateway knows that connection as the run's, so the safety layer can stop what
it drove and the driver lease can be the run's. Each line of its output is published on
/rosgate/runs/ID/output (std_msgs/msg/String), and its state (a JSON text) on
/rosgate/runs/ID/state, latched.

At most ``--max-runs`` runs go at once, ``--max-runs-per-person`` of one signed-in person (an
admin has only the first limit), each in a namespace of the graph (a station like /s07, or the
root): a run's namespace is a name the gateway knows, not any text.

Output past the cap (4 MiB) is not cut into lines: every DRAIN_PERIOD what the pipe holds is read
and thrown away, so a program that floods its output blocks on a full pipe in between instead of
keeping a core of the gateway busy (reading and splitting it as fast as it came took 97 % of one).
"""

from __future__ import annotations

import asyncio
import fcntl
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
import tempfile
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import tornado.httpserver
import tornado.netutil
import tornado.web

from protocol import ops
from protocol.errors import ProtocolError

from ..rules.stations import person_of
from .api import JsonHandler, body_json, caller
from .programs import space_owner, stored_program
from ..settings import data_dir
from ..backends.base import QoS
from ..rules.safety import Safety, moving_command
from .sandbox import (HOME, SOCKET, Cgroups, RunCgroup, Sandbox, SandboxUnavailable, exit_code, kill_box,
                      limits_in_force, run_user)

log = logging.getLogger('rosgate.runs')
STRING = 'std_msgs/msg/String'
OUTPUT_TAIL = 64 * 1024        # bytes of output kept for GET /api/runs/ID
LINE_LIMIT = 4096              # longer lines are cut
KEEP_ENDED = 50                # ended runs kept (with their directories) before the oldest goes
KILL_AFTER = 2.0               # s between SIGINT and SIGKILL
MAX_SOURCE = 1024 * 1024
DRAIN_PERIOD = 0.1             # s between the reads that drop output past the cap
DRAIN_READS = 4                # of PIPE_SIZE each: output past the cap flows at up to 40 MiB/s
PIPE_SIZE = 2**20
CGROUP_GONE = 5.0              # s to wait for a run's cgroup to empty before leaving it behind
RUN_TOPIC = re.compile(r'/rosgate/runs/(r[0-9a-f]{8})/(?:output|state)')
NAMESPACE = re.compile(r'(/[A-Za-z_][A-Za-z0-9_]{0,63}){0,8}')   # ROS names, ASCII, a few levels

# Runs between fork and exec of the program: limits first, then the program replaces it.
# (A preexec_fn would do the same in the gateway's forked child, which is unsafe with the
# threads of the rclpy backend.)
# Before that it starts the relay that serves the gateway's unix socket on the box's loopback: it
# listens first (a program connecting at once finds it there), then a process of its own (a session
# of its own, so the SIGINT of a stop reaches the program and not the relay, whose connection the
# program may still need to stop the robot) accepts and copies each connection both ways, while
# the program starts, so the program never finds its port closed.
LAUNCHER = '''import os, resource, sys
cpu, mem, files, procs = (int(v) for v in sys.argv[1].split(","))
port = int(sys.argv[2])
if port:
    import socket
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(("127.0.0.1", port))
    server.listen(64)
    if os.fork() == 0:
        os.setsid()
        if os.fork() == 0:
            import threading
            def pump(a, b):
                try:
                    while True:
                        data = a.recv(65536)
                        if not data:
                            break
                        b.sendall(data)
                    b.shutdown(socket.SHUT_WR)
                except OSError:
                    for end in (a, b):
                        try:
                            end.shutdown(socket.SHUT_RDWR)
                        except OSError:
                            pass
            def relay(client):
                with client, socket.socket(socket.AF_UNIX) as gateway:
                    try:
                        gateway.connect(sys.argv[3])
                    except OSError:
                        return
                    back = threading.Thread(target=pump, args=(gateway, client), daemon=True)
                    back.start()
                    pump(client, gateway)
                    back.join()
            while True:
                threading.Thread(target=relay, args=(server.accept()[0],), daemon=True).start()
        os._exit(0)
    os.wait()
    server.close()
if cpu: resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 5))
if mem: resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
if files: resource.setrlimit(resource.RLIMIT_NOFILE, (files, files))
if procs: resource.setrlimit(resource.RLIMIT_NPROC, (procs, procs))
os.execv(sys.executable, [sys.executable, "-u", *sys.argv[4:]])
'''


@dataclass(frozen=True)
class RunLimits:
    timeout: float = 600.0          # s, when the request gives none
    max_timeout: float = 3600.0
    cpu_seconds: int = 600
    memory_mb: int = 1024           # address space; Python with roslibpy needs a few hundred MiB
    open_files: int = 256
    processes: int = 512            # threads and processes of the run (its user namespace and cgroup)
    cpus: float = 1.0               # share of the machine's cores with a cgroup
    output_bytes: int = 4 * 2**20   # published per run; past it output is dropped at the pipe


class Run:
    def __init__(self, id: str, name: str, ns: str, timeout: float, workdir: Path):
        self.id, self.name, self.ns, self.timeout, self.workdir = id, name, ns, timeout, workdir
        self.key = secrets.token_urlsafe(24)
        self.state, self.exit_code, self.reason = 'starting', None, None
        self.started, self.ended = time.time(), None
        self.tail: deque[str] = deque()
        self.tail_bytes = 0
        self.sessions: list = []
        self.ending: str | None = None     # 'stopped' or 'timed_out' once we end it
        self.pid: int | None = None        # also its process group
        self.done: asyncio.Future = asyncio.get_running_loop().create_future()
        self.timers: list[asyncio.TimerHandle] = []
        self.output_pub = self.state_pub = None
        self.memory_error = False
        self.role: str | None = None         # the starter's role, given to the run's connection
        self.person: str | None = None       # who started it: the run drives for them (rules.stations)
        self.owner: str | None = None        # the starter's name (None: auth is off)
        self.cgroup: RunCgroup | None = None

    def summary(self) -> dict:
        return {'id': self.id, 'name': self.name, 'ns': self.ns, 'state': self.state,
                'exit_code': self.exit_code, 'reason': self.reason, 'started': self.started,
                'ended': self.ended, 'timeout': self.timeout}

    def detail(self) -> dict:
        return {**self.summary(), 'output': ''.join(self.tail)}

    def keep(self, line: str) -> None:
        self.tail.append(line)
        self.tail_bytes += len(line)
        while self.tail_bytes > OUTPUT_TAIL and len(self.tail) > 1:
            self.tail_bytes -= len(self.tail.popleft())


class _Output(asyncio.SubprocessProtocol):
    """The process's stdout and stderr (one pipe), cut into lines until ``limit`` bytes came (then
    ``on_limit()``; the rest is read in large chunks now and then and thrown away), and when it ends."""

    def __init__(self, on_line, on_limit, limit: int, loop):
        self.on_line, self.on_limit, self.limit, self.loop = on_line, on_limit, limit, loop
        self.pending = b''
        self.received = 0
        self.pipe = None
        self.drain: asyncio.TimerHandle | None = None
        self.exited, self.eof = loop.create_future(), loop.create_future()

    def connection_made(self, transport) -> None:
        self.pipe = transport.get_pipe_transport(1)
        try:      # fewer, larger reads (1 MiB is what an unprivileged process may ask by default)
            fcntl.fcntl(self.pipe.get_extra_info('pipe').fileno(), fcntl.F_SETPIPE_SZ, PIPE_SIZE)
        except (OSError, AttributeError):
            pass

    def pipe_data_received(self, fd: int, data: bytes) -> None:
        if self.received > self.limit:
            self._drop()
            return
        self.received += len(data)
        over = self.received > self.limit
        if over:
            data = data[:len(data) - (self.received - self.limit)]
        self.pending += data
        *lines, self.pending = self.pending.split(b'\n')
        for line in lines:
            self.on_line(line[:LINE_LIMIT].decode('utf-8', 'replace') + '\n')
        if len(self.pending) > LINE_LIMIT:
            self.on_line(self.pending[:LINE_LIMIT].decode('utf-8', 'replace') + '\n')
            self.pending = b''
        if over:
            self.pending = b''
            self.on_limit()
            self._drop()

    def _drop(self) -> None:
        """Past the limit: read again (and drop what comes) only after DRAIN_PERIOD."""
        if self.pipe is not None and self.drain is None:
            self.pipe.pause_reading()
            self.drain = self.loop.call_later(DRAIN_PERIOD, self._resume)

    def _resume(self) -> None:
        """Drop what the pipe holds (up to a few MiB) with reads of our own, then let the transport
        read again: the next thing it reads (or its end) comes to pipe_data_received."""
        self.drain = None
        if self.pipe.is_closing():
            return
        try:
            fd = self.pipe.get_extra_info('pipe').fileno()
            for _ in range(DRAIN_READS):
                if not os.read(fd, PIPE_SIZE):
                    break             # its end: the transport sees it too
        except OSError:               # BlockingIOError: empty
            pass
        self.pipe.resume_reading()

    def pipe_connection_lost(self, fd: int, exc) -> None:
        if self.drain is not None:
            self.drain.cancel()
        if self.pending:
            self.on_line(self.pending.decode('utf-8', 'replace') + '\n')
            self.pending = b''
        if not self.eof.done():
            self.eof.set_result(None)

    def process_exited(self) -> None:
        if not self.exited.done():
            self.exited.set_result(None)


class RunManager:
    def __init__(self, gateway, *, allowed: bool, runs_dir: Path | None, limits: RunLimits = RunLimits(),
                 box: Sandbox | None = None, cgroups: Cgroups | None = None, max_runs: int = 4,
                 max_per_person: int = 2):
        self.gateway, self.allowed, self.limits = gateway, allowed, limits
        self.runs_dir = runs_dir
        self.box, self.cgroups = box, cgroups
        self.max_runs, self.max_per_person = max_runs, max_per_person
        self.runs: dict[str, Run] = {}
        self.server: tornado.httpserver.HTTPServer | None = None
        self.home: Path | None = None       # the box's files of the gateway's: the unix socket, staged views

    def serve(self, app, sock) -> None:
        """Serve ``app`` (the rosbridge websocket alone) on the unix socket that the boxes bind in:
        the runs' one way to the gateway."""
        settings = self.gateway.settings
        self.server = tornado.httpserver.HTTPServer(app, max_buffer_size=settings.max_message_size * 4,
                                                    idle_connection_timeout=settings.idle_connection_timeout)
        self.server.add_socket(sock)

    # --- starting -----------------------------------------------------------------------------

    def start(self, source: str, name: str, ns: str, timeout: float, role: str | None, port: tuple[str, int, bool],
              person: str | None = None):
        """A new Run, its process being started; raises HTTPError 404 for a namespace the graph does
        not have, 409 when the namespace is busy or its lease is not the starter's, 429 past the
        limits on runs going at once. person: who starts it (rules.stations.person_of), for whom
        the run drives."""
        self._known(ns)
        going = [r for r in self.runs.values() if r.state in ('starting', 'running')]
        busy = next((r for r in going if r.ns == ns), None)
        if busy is not None:
            where = f'namespace {ns}' if ns else 'the root namespace'
            raise tornado.web.HTTPError(409, f'run {busy.id} ({busy.name}) is already running in {where}; '
                                             f'stop it first (DELETE /api/runs/{busy.id})')
        if len(going) >= self.max_runs:
            raise tornado.web.HTTPError(429, f'{len(going)} runs are going, the most this gateway runs at once '
                                             '(--max-runs); wait for one to end or stop one')
        mine = [r for r in going if person is not None and r.person == person]
        if role != 'admin' and len(mine) >= self.max_per_person:
            raise tornado.web.HTTPError(429, f'{person} has {len(mine)} runs going ({", ".join(r.id for r in mine)}), '
                                             'the most one person may (--max-runs-per-person); stop one first')
        run_id = 'r' + secrets.token_hex(4)
        person = person or f'run {run_id}'
        self._lease_free_for(person, role, ns)
        workdir = self.runs_dir / run_id
        try:
            workdir.mkdir(parents=True, mode=0o700)
            (workdir / 'program.py').write_text(source)
        except OSError as e:
            raise tornado.web.HTTPError(500, f'cannot prepare the run directory: {e}') from None
        run = Run(run_id, name, ns, timeout, workdir)
        run.role, run.person = role, person
        latched = QoS(depth=1, transient_local=True)
        gateway = self.gateway
        run.state_pub = gateway.own_topic(f'/rosgate/runs/{run_id}/state', STRING, latched)
        run.output_pub = gateway.own_topic(f'/rosgate/runs/{run_id}/output', STRING, QoS(depth=100))
        self.runs[run_id] = run
        self._forget_old()
        self._announce(run)
        task = asyncio.ensure_future(self._supervise(run, port))
        task.add_done_callback(lambda t: t.cancelled() or t.exception() is None or log.error(
            'run %s: supervising it failed', run.id, exc_info=t.exception()))
        return run

    def namespaces(self) -> set[str]:
        """The root and the namespaces of the graph's nodes (/s07 of /s07/turtlesim, and so on)."""
        known = {''}
        for node in self.gateway.backend.nodes():
            parts = node.strip('/').split('/')[:-1]
            known.update('/' + '/'.join(parts[:i]) for i in range(1, len(parts) + 1))
        return known

    def _known(self, ns: str) -> None:
        known = self.namespaces()
        if ns not in known:
            names = ', '.join(sorted(n for n in known if n)[:20]) or 'none but the root'
            raise tornado.web.HTTPError(404, f'no robot namespace {ns} on this gateway (namespaces: {names})')

    def _lease_free_for(self, person: str, role: str | None, ns: str) -> None:
        """With --exclusive-control a run takes its namespace's driver lease (from its starter's own
        page quietly, and gives it back when it ends): refuse at once a run that could not (another
        person's station or lease, or a stop that holds until Take)."""
        lease = getattr(self.gateway.policy, 'lease', None)
        why = lease.run_refusal(person, role, ns) if lease is not None else None
        if why is not None:
            raise tornado.web.HTTPError(409, why)

    def _env(self, run: Run, url: str) -> dict:
        """Only what a Python program needs: none of the gateway's own environment (tokens, keys).
        bwrap hands it on as it is (the run key stays out of every command line)."""
        graph = dict(self.box.environment) if self.box is not None else {}   # --trusted-runs
        return {**graph, 'PATH': '/usr/bin:/bin', 'HOME': HOME, 'LANG': 'C.UTF-8', 'PYTHONUNBUFFERED': '1',
                'PYTHONDONTWRITEBYTECODE': '1', 'ROSBRIDGE_URL': url, 'ROSGATE_NS': run.ns,
                'ROSGATE_RUN': run.id}

    async def _supervise(self, run: Run, port: tuple[str, int, bool]) -> None:
        host, number, tls = port
        path = self.gateway.settings.url_path
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
        if run.ns:
            command += ['--ns', run.ns]
        if self.cgroups is not None:
            run.cgroup = self.cgroups.make(run.id, lim.memory_mb * 2**20, lim.processes, lim.cpus)
        loop = asyncio.get_running_loop()
        output = _Output(lambda line: self._line(run, line), lambda: self._limit_reached(run),
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

    def _safety(self) -> Safety | None:
        return next((h for h in self.gateway.hooks if isinstance(h, Safety)), None)

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
        self._announce(run)
        run.done.set_result(run.state)
        log.info('run %s (%s) %s%s', run.id, run.name, run.state, f': {reason}' if reason else '')
        if run.cgroup is not None:
            self._remove_cgroup(run.cgroup, time.monotonic() + CGROUP_GONE)

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
        lease = getattr(self.gateway.policy, 'lease', None)
        if lease is not None:
            try:
                lease.take(session, run.ns)
            except ProtocolError as e:
                self._line(run, f'[driver lease: {e.message}]\n', ours=True)

    def subscribe_guard(self, session, op) -> None:
        """A run's output and state topics are its starter's and the admins', as GET is."""
        found = RUN_TOPIC.fullmatch(op.topic) if isinstance(op, ops.Subscribe) else None
        run = self.runs.get(found.group(1)) if found else None
        if run is None or getattr(self.gateway.policy, 'auth', None) is None:
            return
        attrs = session.attrs
        if attrs.get('role') == 'admin' or attrs.get('run') == run.id or (
                run.owner is not None and attrs.get('person') == run.person):
            return
        raise ProtocolError(f'{op.topic}: run {run.id} was started by {run.owner or "someone else"}; its output '
                            'and state are for them and admins', op=op.OP, id=op.id)

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
        left = [r.cgroup for r in self.runs.values() if r.cgroup is not None]
        deadline = time.monotonic() + 1.0
        while left and time.monotonic() < deadline:     # each goes once the kernel has emptied it
            left = [c for c in left if not c.remove()]
            if left:
                await asyncio.sleep(0.02)


# --- HTTP ---------------------------------------------------------------------------------------

def _local_address(handler) -> tuple[str, int, bool]:
    """Where this request reached us (the run connects back the same way, on this machine)."""
    sock = handler.request.connection.stream.socket
    host, port = sock.getsockname()[:2]
    if host in ('0.0.0.0', '::'):
        host = '127.0.0.1'
    return host, port, handler.request.protocol == 'https'


def may_see(identity, run: Run) -> bool:
    """A run's state and output are its starter's and the admins' (everyone's with auth off)."""
    return identity is None or identity.role == 'admin' or run.owner == identity.owner


class RunListHandler(JsonHandler):
    def initialize(self, manager: RunManager) -> None:
        self.manager = manager

    def get(self) -> None:
        identity = caller(self, self.manager.gateway)
        runs = [r.summary() for r in self.manager.runs.values() if may_see(identity, r)]
        self.finish({'allowed': self.manager.allowed, 'runs': runs})

    def post(self) -> None:
        m = self.manager
        if not m.allowed:
            raise tornado.web.HTTPError(403, 'runs are off on this gateway (start it with --allow-runs)')
        identity = caller(self, m.gateway, change=True, roles=('operator', 'admin'))
        body = body_json(self, MAX_SOURCE)
        source = body.get('source')
        if source is None and body.get('program') is not None:
            source = self._library(str(body['program']), identity, body.get('owner'))
        if not isinstance(source, str) or not source.strip():
            raise tornado.web.HTTPError(400, 'give "source" (the Python program) or "program" (a library name)')
        name = body.get('name') or body.get('program') or 'program'
        if not isinstance(name, str) or len(name) > 64:
            raise tornado.web.HTTPError(400, '"name" is a text of at most 64 characters')
        ns = body.get('ns') or ''
        if isinstance(ns, str) and len(ns) <= 200:
            ns = '/' + '/'.join(p for p in ns.split('/') if p) if ns.strip('/') else ''
        if not isinstance(ns, str) or not NAMESPACE.fullmatch(ns):
            shown = repr(ns[:40]) + ('...' if len(ns) > 40 else '') if isinstance(ns, str) else repr(ns)
            raise tornado.web.HTTPError(400, f'"ns" is a robot namespace like /s07 (ASCII letters, digits and _), '
                                             f'not {shown}')
        timeout = body.get('timeout', m.limits.timeout)
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not 0 < timeout <= m.limits.max_timeout:
            raise tornado.web.HTTPError(400, f'"timeout" is a number of seconds, 0 < timeout <= {m.limits.max_timeout:g}')
        role = identity.role if identity is not None else None
        run = m.start(source, name, ns, float(timeout), role, _local_address(self),
                      person_of(identity, self.request.cookies))
        run.owner = identity.owner if identity is not None else None
        self.set_status(201)
        self.finish({'id': run.id, **run.summary()})

    def _library(self, name: str, identity, owner) -> str:
        """The Python stored with a library program, from the space the library would open for
        this caller: an operator's own (with --auth), else the shared one or an admin's "owner"."""
        programs_dir = self.manager.gateway.settings.programs_dir
        owner = space_owner(identity, owner, 'run')
        if programs_dir is None or not (owner is None or isinstance(owner, str) and owner):
            raise tornado.web.HTTPError(400, f'no program library entry {name!r}')
        try:
            stored = stored_program(programs_dir, name, owner)
        except FileNotFoundError:
            raise tornado.web.HTTPError(404, f'no program named {name!r} in the library') from None
        except ValueError as e:
            raise tornado.web.HTTPError(400, str(e)) from None
        source = stored.get('python')
        if not isinstance(source, str):
            raise tornado.web.HTTPError(422, f'program {name!r} was saved without its Python; send "source"')
        return source


class RunHandler(JsonHandler):
    def initialize(self, manager: RunManager) -> None:
        self.manager = manager

    def _run(self, run_id: str) -> Run:
        run = self.manager.runs.get(run_id)
        if run is None:
            raise tornado.web.HTTPError(404, f'no run {run_id!r}')
        return run

    def get(self, run_id: str) -> None:
        identity = caller(self, self.manager.gateway)
        run = self._run(run_id)
        if not may_see(identity, run):
            raise tornado.web.HTTPError(403, f'run {run.id} was started by {run.owner or "someone else"}; its state '
                                             f'and output are for them and admins, not {identity.name}')
        self.finish(run.detail())

    def delete(self, run_id: str) -> None:
        identity = caller(self, self.manager.gateway, change=True, roles=('operator', 'admin'))
        run = self._run(run_id)
        if identity is not None and identity.role != 'admin' and run.owner != identity.owner:
            raise tornado.web.HTTPError(403, f'run {run.id} was started by {run.owner or "someone else"}; '
                                             f'{identity.name} may not stop it')
        self.manager.stop(run)
        self.set_status(202 if run.ended is None else 200)
        self.finish(run.summary())


def run_routes(gateway, socket_app=None) -> list:
    """The /api/runs routes; their manager joins the gateway's hooks and serves ``socket_app`` (the
    websocket alone) to the runs on a unix socket. With --allow-runs and no working bwrap the
    gateway does not start (SystemExit naming what to install)."""
    settings = gateway.settings
    runs_dir = Path(settings.runs_dir or default_runs_dir())
    box = cgroups = home = sock = None
    if settings.trusted_runs and not settings.allow_runs:
        raise SystemExit('rosgate: --trusted-runs is a kind of run: give --allow-runs too')
    if settings.allow_runs:
        private = [settings.programs_dir, runs_dir, settings.record, data_dir(''), settings.certfile,
                   settings.keyfile, Path.home(), *(a for a in sys.argv[1:] if a.startswith('/'))]
        sweep_homes()
        home = Path(tempfile.mkdtemp(prefix=f'{HOME_PREFIX}{os.getpid()}-'))
        try:
            user = run_user()
            sock = None     # a trusted run, on the machine's network, reaches the gateway's port itself
            if not settings.trusted_runs:
                sock = tornado.netutil.bind_unix_socket(str(home / 'gateway.sock'), mode=0o600 if user is None else 0o660)
            if user is not None:     # the runs' user reaches the socket through its group (else it is ours)
                os.chown(home, 0, user[1])
                if sock is not None:
                    os.chown(home / 'gateway.sock', 0, user[1])
                home.chmod(0o750)
            box = Sandbox.create(private, home=home, socket=None if sock is None else str(home / 'gateway.sock'),
                                 graph=settings.trusted_runs)
        except SandboxUnavailable as e:
            shutil.rmtree(home, ignore_errors=True)
            raise SystemExit(f'rosgate: {e}') from None
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
    manager = RunManager(gateway, allowed=settings.allow_runs, runs_dir=runs_dir, box=box, cgroups=cgroups,
                         max_runs=settings.max_runs, max_per_person=settings.max_runs_per_person)
    manager.home = home          # removed at shutdown
    if sock is not None and socket_app is not None:
        manager.serve(socket_app, sock)
    gateway.hooks.append(manager)
    gateway.rules.insert(0, manager.publish_hook)
    gateway.guards.append(manager.subscribe_guard)
    kw = {'manager': manager}
    return [(r'/api/runs/?', RunListHandler, kw), (r'/api/runs/(r[0-9a-f]{8})/?', RunHandler, kw),
            (r'/api/runs/([^/]+)', RunHandler, kw)]


def default_runs_dir() -> Path:
    return data_dir('runs')


HOME_PREFIX = 'rosgate-box-'


def sweep_homes() -> None:
    """Remove the socket folders of gateways that are gone (killed before they could)."""
    for d in Path(tempfile.gettempdir()).glob(f'{HOME_PREFIX}*-*'):
        pid = d.name[len(HOME_PREFIX):].split('-')[0]
        if pid.isdigit() and not Path(f'/proc/{pid}').exists():
            shutil.rmtree(d, ignore_errors=True)
