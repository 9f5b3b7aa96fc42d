"""The box a robot-side run lives in: bubblewrap (``bwrap``) namespaces, a read-only view of the
interpreter, and cgroup limits where this machine lets the gateway make cgroups.

Why bwrap: it is one small program (Debian package ``bubblewrap``, what Flatpak uses) that builds
user, pid, mount, ipc and uts namespaces without privileges where unprivileged user namespaces are
on, and as root. A run then sees:

- a file system of its own: /usr (and the /bin, /lib... links into it), a few files of /etc, the
  interpreter's prefixes (a venv and the Python it was made from) read-only; a private /tmp and
  home (tmpfs, size-capped) holding its program; a /proc of its own pid namespace, a minimal /dev.
  Not the gateway's data, programs, recordings, tokens, TLS key or checkout (a path of the
  gateway's own command line that falls inside the view is masked).
- no other process: it is in a pid namespace whose init is bwrap's. When that init dies, the kernel
  kills every process of the namespace, however it forked or setsid'd away: the program ending,
  SIGKILL to the init (stop, timeout) and the gateway dying (``--die-with-parent``) all end the
  whole tree.
- a network of its own (``--unshare-net``: a loopback and nothing else; no DDS, no multicast, no port
  of this machine). Its one way out is the gateway's websocket: the gateway also listens on a unix
  socket, bound into the box at /run/rosgate.sock, and a relay (a process the run's launcher forks
  before the program; see runs.py) serves it on the box's 127.0.0.1 at the gateway's own port
  number, so ``ROSBRIDGE_URL``, roslibpy and the generated Python work unchanged.
- uid 1000 inside, with no capabilities and no further user namespaces (``--disable-userns``), and
  never uid 0 outside: a gateway running as root starts bwrap as an unprivileged user (the system
  user ``rosgate-run`` where the guide's step made it, else ``nobody``) through ``setpriv``, so
  bwrap's user namespace maps the run to that uid. That user must be able to read the interpreter
  (the venv and the Python it was made from): an interpreter it cannot reach (a pyenv Python under
  /root, mode 700) is first bound, by root in a mount namespace of the start's own, to a folder it
  can reach; an interpreter it cannot read refuses ``--allow-runs``. The one exception: a gateway
  that is uid 0 of a user namespace mapping uid 0 alone to the machine's root (``unshare -rn`` run
  by root) has no other uid to give; its runs are that root (the box still holds them: read-only
  files, no capabilities, no network), and its start-up log says so in a warning.

Measured on a 2-core VM (``python -m tests.bench.run_start``, medians of 15 runs, interleaved with
the same on the code before the sandbox): the box and its cgroup add 15 to 25 ms to a start, from
POST to the program's first statement 43 -> 58 ms, to a program that imports roslibpy, connects
and logs 260 -> 285 ms. Its own network, the relay and the unprivileged uid outside (as root)
add about 8 ms more to the first (89 -> 97 ms) and 50 ms to the second (704 -> 756 ms), medians
of 21 taken in turn with the code before on a machine at load 10 (``--compare``).

bwrap's init reports a program killed by signal N as exit code 128 + N, as a shell does; see
``exit_code``.
"""

from __future__ import annotations

import functools
import logging
import os
import pwd
import shutil
import stat
import signal
import site
import subprocess
import sys
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger('rosgate.sandbox')
PACKAGE = 'bubblewrap'          # the Debian/Ubuntu package that has bwrap
HOME = '/home/run'              # the run's working directory and $HOME, where its program is
UID = 1000                      # its user and group inside
RUN_USER = 'rosgate-run'        # who runs are outside when the gateway is root (else nobody)
SOCKET = '/run/rosgate.sock'    # the gateway's websocket inside the box (a unix socket)
STAGE = 'while [ "$1" != -- ]; do mount --bind "$1" "$2" || exit 125; shift 2; done; shift; exec "$@"'
ETC = ('ld.so.cache', 'ld.so.conf', 'ld.so.conf.d', 'localtime', 'hosts', 'host.conf', 'nsswitch.conf',
       'gai.conf', 'ssl/certs', 'ssl/openssl.cnf', 'ca-certificates')   # not ssl/private
ROOT_LINKS = ('bin', 'sbin', 'lib', 'lib32', 'lib64', 'libx32')


GRAPH_VARIABLES = ('ROS_', 'RMW_', 'FASTDDS_', 'FASTRTPS_', 'CYCLONEDDS_', 'AMENT_PREFIX_PATH')


def graph_env(shown: list[Path], environ=None) -> dict:
    """What a run on the graph (--trusted-runs) takes of the gateway's environment: its ROS and
    DDS variables, and the library and module paths that lie in what the box shows (``shown``,
    and /usr)."""
    environ = os.environ if environ is None else environ
    env = {k: v for k, v in environ.items() if k.startswith(GRAPH_VARIABLES)}
    shown = [*shown, Path('/usr')]
    for name in ('PYTHONPATH', 'LD_LIBRARY_PATH'):
        kept = [p for p in environ.get(name, '').split(os.pathsep)
                if p and os.path.isabs(p) and _within(Path(os.path.realpath(p)), shown)]
        if kept:
            env[name] = os.pathsep.join(kept)
    return env


def ament_prefixes(environ=None) -> list[Path]:
    """The ROS installs the gateway was started in (AMENT_PREFIX_PATH: /opt/ros/jazzy, a workspace)."""
    environ = os.environ if environ is None else environ
    found = []
    for p in environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        path = Path(os.path.realpath(p)) if p and os.path.isabs(p) else None
        if path is not None and path.is_dir() and not _within(path, [Path('/usr'), *found]):
            found.append(path)
    return found


class SandboxUnavailable(Exception):
    """bwrap is missing or cannot build its namespaces here; the message says what to do."""


def _within(path: Path, parents) -> bool:
    return any(path == p or p in path.parents for p in parents)


def interpreter_paths() -> list[Path]:
    """What the run's interpreter needs outside /usr: its prefixes and site-packages (a venv and
    the Python it was made from), outermost first."""
    found = []
    for p in (sys.base_prefix, sys.base_exec_prefix, sys.prefix, sys.exec_prefix, *site.getsitepackages(),
              os.path.dirname(os.path.realpath(sys.executable))):
        path = Path(os.path.realpath(p))
        if path.is_dir() and not _within(path, [Path('/usr'), *found]):
            found = [f for f in found if not _within(f, [path])] + [path]
    return found


@dataclass(frozen=True)
class Outside:
    """Who a run is outside the box: bwrap is started as ``uid``/``gid`` through setpriv (None: as
    the gateway itself, which is not root), after ``stage`` (pairs of paths) is bound by root in a
    mount namespace of the start's own."""
    uid: int | None = None
    gid: int | None = None
    name: str = ''
    stage: tuple[str, ...] = ()

    def prefix(self) -> list[str]:
        """What goes before bwrap on its command line."""
        if self.uid is None:
            return []
        drop = ['setpriv', f'--reuid={self.uid}', f'--regid={self.gid}', '--clear-groups', '--inh-caps=-all',
                '--no-new-privs', '--']
        if not self.stage:
            return drop
        return ['unshare', '--mount', '--propagation', 'private', '--', '/bin/sh', '-c', STAGE, 'rosgate-stage',
                *self.stage, '--', *drop]


@dataclass(frozen=True)
class Sandbox:
    bwrap: str
    mounts: tuple[str, ...]          # bwrap arguments that build the file system view
    options: tuple[str, ...]         # namespace arguments this bwrap understands
    tmp_bytes: int
    outside: Outside = Outside()
    socket: str | None = None        # the gateway's unix socket, bound into the box at SOCKET
    graph: bool = False              # --trusted-runs: the machine's network, on the ROS graph
    environment: tuple = ()          # (name, value) pairs of the gateway's a run takes (graph_env)

    @classmethod
    def create(cls, private=(), tmp_bytes: int = 64 * 2**20, bwrap: str | None = None, home: Path | None = None,
               socket: str | None = None, graph: bool = False) -> Sandbox:
        """The sandbox for this interpreter; ``private``: paths to keep out of the view (masked
        where they fall inside it); ``home``: a folder of the gateway's own for the box's files
        (the unix socket, the mount points of a staged interpreter); ``socket``: the gateway's unix
        socket there; ``graph`` (--trusted-runs): no network of its own, and the ROS installs of
        AMENT_PREFIX_PATH in view, so that the run is a node of the graph. Raises
        SandboxUnavailable, saying what to install or change."""
        found = bwrap or shutil.which('bwrap')
        if not found:
            raise SandboxUnavailable(f'--allow-runs runs programs in a bubblewrap sandbox and bwrap is not installed '
                                     f'here: install the Debian package {PACKAGE} (apt-get install {PACKAGE})')
        try:
            help_text = subprocess.run([found, '--help'], capture_output=True, text=True, timeout=10).stdout
        except (OSError, subprocess.SubprocessError) as e:
            raise SandboxUnavailable(f'{found} does not run: {e}') from None
        options = ['--unshare-user', '--uid', str(UID), '--gid', str(UID), '--unshare-pid', '--unshare-ipc',
                   *([] if graph else ['--unshare-net']), '--unshare-uts', '--hostname', 'run',
                   '--unshare-cgroup-try', '--die-with-parent', '--new-session', '--cap-drop', 'ALL']
        if '--disable-userns' in help_text:          # bwrap >= 0.8
            options.append('--disable-userns')
        sized = '--size' in help_text                 # bwrap >= 0.5
        user = run_user()
        shown = interpreter_paths()
        if graph:
            shown += [p for p in ament_prefixes() if not _within(p, shown)]
        stage: list[str] = []
        sources = {}
        if user is not None:
            for i, path in enumerate(shown):
                why = unreadable(path, *user[:2])
                if why is not None:
                    raise SandboxUnavailable(
                        f'runs run as {user[2]} (uid {user[0]}) outside their box and {why}: the interpreter and '
                        f'its venv must be readable by others (chmod -R o+rX {path}), or start the gateway from '
                        'a venv that is')
                if not reachable(path, *user[:2]):
                    if home is None:
                        raise SandboxUnavailable(f'{user[2]} cannot reach {path}')
                    point = home / 'view' / str(i)
                    point.mkdir(parents=True, exist_ok=True)
                    stage += [str(path), str(point)]
                    sources[path] = point
        if user is not None and home is not None and not reachable(home, *user[:2]):
            raise SandboxUnavailable(f'{user[2]} cannot reach {home} (where the gateway keeps the runs\' socket)')
        outside = Outside(*user, tuple(stage)) if user is not None else Outside()
        box = cls(found, tuple(_mounts(private, shown, sources)), tuple(options), tmp_bytes if sized else 0, outside,
                  socket, graph, tuple(graph_env(shown).items()) if graph else ())
        box.probe()
        return box

    def argv(self, command: list[str], program_fd: int | None = None) -> list[str]:
        """bwrap running ``command`` in the box, cwd and $HOME /home/run, with the file open at
        ``program_fd`` there read-only as program.py. The environment is the caller's (give only
        what the run needs)."""
        size = lambda: ['--size', str(self.tmp_bytes)] if self.tmp_bytes else []   # noqa: E731
        # the private /tmp first: an interpreter (a checkout's venv) under /tmp is bound over it
        a = [self.bwrap, *self.options, '--perms', '1777', *size(), '--tmpfs', '/tmp', *self.mounts,
             '--proc', '/proc', '--dev', '/dev', *size(), '--tmpfs', HOME]
        if self.graph:            # DDS's shared memory transport (Fast DDS's default between local peers)
            a += ['--bind-try', '/dev/shm', '/dev/shm']
        if self.socket is not None:
            a += ['--ro-bind', self.socket, SOCKET]
        if program_fd is not None:
            a += ['--ro-bind-data', str(program_fd), f'{HOME}/program.py']
        return [*self.outside.prefix(), *a, '--chdir', HOME, '--', *command]

    @contextmanager
    def launch(self, command: list[str], program: Path):
        """(argv, pass_fds) to start ``command`` in the box with ``program``: bwrap reads its
        options from a pipe and the program from an open file, so the box's /proc/1 (bwrap is its
        init), its mount table and ps on this machine show no path of the gateway's (the runs
        folder, the data folder) but the interpreter's."""
        program_fd = os.open(program, os.O_RDONLY | os.O_CLOEXEC)
        read, write = os.pipe()
        try:
            prefix = self.outside.prefix()
            options = self.argv([], program_fd)[len(prefix) + 1:-1]      # the command stays on the command line
            args = b''.join(a.encode() + b'\0' for a in options)
            if len(args) > 60000:     # a pipe holds 64 KiB: written at once, it never blocks
                raise ValueError(f'{len(args)} bytes of bwrap arguments')
            os.write(write, args)
            os.close(write)
            write = None
            yield [*prefix, self.bwrap, '--args', str(read), '--', *command], (read, program_fd)
        finally:
            for fd in (read, write, program_fd):
                if fd is not None:
                    os.close(fd)

    def probe(self) -> None:
        """Start the interpreter in the box once: bwrap installed but unable to make namespaces
        (user namespaces off), or an interpreter the run's user cannot read, shows here, at
        start-up, not at the first run."""
        try:
            done = subprocess.run(self.argv([sys.executable, '-I', '-c', 'pass']), capture_output=True, text=True,
                                  timeout=30, env={'PATH': os.defpath}, stdin=subprocess.DEVNULL)
        except (OSError, subprocess.SubprocessError) as e:
            raise SandboxUnavailable(f'bwrap does not run: {e}') from None
        if done.returncode != 0:
            why = (done.stderr or done.stdout).strip()[-500:]
            who = f' as {self.outside.name} (uid {self.outside.uid})' if self.outside.uid is not None else ''
            raise SandboxUnavailable(
                f'bwrap cannot build the sandbox for runs here{who} ({why or f"exit code {done.returncode}"}); '
                'unprivileged user namespaces may be off (sysctl kernel.unprivileged_userns_clone=1, or on '
                'Ubuntu 24.04 and later kernel.apparmor_restrict_unprivileged_userns=0)')


@functools.cache         # a fact of this process (and its warning said once)
def run_user() -> tuple[int, int, str] | None:
    """(uid, gid, name) that runs have outside when the gateway is root: RUN_USER where it exists,
    else nobody; None when the gateway is not root (bwrap maps the run to the gateway's own uid),
    or when it is uid 0 of a user namespace where no other uid exists (``unshare -r``): there a
    warning says that runs are root outside when that uid 0 is the machine's root."""
    if os.geteuid() != 0:
        return None
    for name in (RUN_USER, 'nobody'):
        try:
            entry = pwd.getpwnam(name)
        except KeyError:
            continue
        if entry.pw_uid != 0 and _mapped(entry.pw_uid):
            return entry.pw_uid, entry.pw_gid, name
    if _outer_uid(0) == 0:
        log.warning(ROOT_ALONE)
    return None


ROOT_ALONE = ('runs are uid 0 outside their box: this gateway is uid 0 of a user namespace that maps uid 0 alone '
              f'(to the machine\'s root), with no other uid ({RUN_USER} or nobody) to give them. Start it as root '
              'outside a user namespace (a network namespace of its own is fine: unshare -n), as an ordinary '
              'user, or in a user namespace that maps more uids')


def _uid_map() -> list[tuple[int, int, int]]:
    try:
        lines = Path('/proc/self/uid_map').read_text().splitlines()
    except OSError:
        return [(0, 0, 2**32 - 1)]
    return [tuple(int(v) for v in line.split()) for line in lines if len(line.split()) == 3]


def _mapped(uid: int) -> bool:
    return _outer_uid(uid) is not None


def _outer_uid(uid: int) -> int | None:
    """``uid`` of our user namespace as its parent namespace sees it (None: not mapped)."""
    for inside, outside, count in _uid_map():
        if inside <= uid < inside + count:
            return outside + uid - inside
    return None


def _allowed(st: os.stat_result, uid: int, gid: int, bits: int) -> bool:
    """Whether uid (with gid and no other group) has the rwx ``bits`` (as for others: 0o5) on it."""
    if st.st_uid == uid:
        return st.st_mode & (bits << 6) == bits << 6
    if st.st_gid == gid:
        return st.st_mode & (bits << 3) == bits << 3
    return st.st_mode & bits == bits


def reachable(path: Path, uid: int, gid: int) -> bool:
    """Whether uid can walk to ``path`` (search permission on every folder above it)."""
    for parent in reversed(Path(path).parents):
        try:
            if not _allowed(os.stat(parent), uid, gid, 0o1):
                return False
        except OSError:
            return False
    return True


def unreadable(path: Path, uid: int, gid: int) -> str | None:
    """Why uid cannot read the folder ``path`` and the Python in it (None: it can)."""
    for p in (path, path / 'bin', path / 'lib'):
        try:
            st = os.stat(p)
        except OSError:
            continue
        if not _allowed(st, uid, gid, 0o5):
            return f'{p} is mode {stat.filemode(st.st_mode)} owned by uid {st.st_uid}'
    return None


def _mounts(private, shown: list[Path], sources: dict) -> list[str]:
    """The read-only view: /usr, the root links into it, some of /etc, the interpreter (each
    folder from where it is staged, if it is)."""
    a = ['--ro-bind', '/usr', '/usr']
    for name in ROOT_LINKS:
        path = Path('/', name)
        if path.is_symlink():
            a += ['--symlink', os.readlink(path), str(path)]
        elif path.is_dir():
            a += ['--ro-bind', str(path), str(path)]
    for name in ETC:
        a += ['--ro-bind-try', f'/etc/{name}', f'/etc/{name}']
    prefix = Path(sys.prefix)          # a venv reached through a link (a checkout's .venv) is seen there
    seen_at = {Path(os.path.realpath(prefix)): prefix} if prefix.is_absolute() else {}
    for path in shown:
        a += ['--ro-bind', str(sources.get(path, path)), str(seen_at.get(path, path))]
    for path in sorted({Path(os.path.realpath(p)) for p in private if p}):
        if _within(path, shown) and path.exists():       # e.g. a data folder inside the venv
            a += ['--tmpfs', str(path)] if path.is_dir() else ['--ro-bind', '/dev/null', str(path)]
    return a


def exit_code(returncode: int | None) -> int | None:
    """The program's exit code as subprocess reports it (negative: the signal that ended it): bwrap
    passes on 128 + N for a program killed by signal N, and that is read back as -N (a program that
    exits with 129..192 by itself reads as killed)."""
    if returncode is not None and 128 < returncode <= 128 + 64:
        return -(returncode - 128)
    return returncode


def init_pid(outer: int) -> int | None:
    """The pid (in ours) of the box's init, the one child of the bwrap process we started; None
    before bwrap made it or after it ended. The program is in its process group."""
    try:
        children = Path(f'/proc/{outer}/task/{outer}/children').read_text().split()
    except OSError:
        return None
    return int(children[0]) if children else None


def kill_box(outer: int, sig: int) -> None:
    """SIGKILL: the init (the kernel then kills everything in the box) and bwrap; other signals:
    the program's process group (processes that setsid'd away do not get them)."""
    init = init_pid(outer)
    targets = [(os.killpg, init)] if sig != signal.SIGKILL else [(os.kill, init), (os.kill, outer)]
    for kill, pid in targets:
        if pid is None:
            continue
        try:
            kill(pid, sig)
        except (ProcessLookupError, PermissionError):
            pass


# --- cgroups ------------------------------------------------------------------------------------

CGROUP_FS = Path('/sys/fs/cgroup')
JOIN = 'while [ "$1" != -- ]; do echo 0 > "$1" || exit 125; shift; done; shift; exec "$@"'


@dataclass(frozen=True)
class Cgroups:
    """Where each run gets a cgroup with memory, process and CPU limits: under the gateway's own
    cgroup, in cgroup v2 when its controllers are (or can be) delegated to children, else in the
    v1 memory, pids and cpu hierarchies when they are writable. None of that is required: without
    it a run has its rlimits only."""
    parents: tuple[tuple[str, Path], ...]     # (controller, directory); v2: one ('v2', directory)
    v2_controllers: tuple[str, ...] = ('memory', 'pids', 'cpu')   # v2: those enabled for the runs

    @classmethod
    def find(cls, fs: Path = CGROUP_FS, own: str | None = None, want=('memory', 'pids', 'cpu'),
             need=('memory', 'pids')) -> tuple[Cgroups | None, str]:
        """The cgroups the runs can have here and a sentence saying so (or why not). ``want``:
        the controllers asked for, ``need``: those without which runs get no cgroup at all."""
        try:
            own = own if own is not None else Path('/proc/self/cgroup').read_text()
        except OSError as e:
            return None, f'no cgroups ({e})'
        lines = [line.split(':', 2) for line in own.splitlines() if line.count(':') >= 2]
        if (fs / 'cgroup.controllers').exists():
            path = next((p for h, c, p in lines if h == '0'), None)
            if path is None:
                return None, 'no cgroup v2 entry in /proc/self/cgroup'
            found, how = _v2(fs / path.lstrip('/'), want, need)
            if found is not None or want != ('memory', 'pids', 'cpu'):
                return found, how
            scopes, why = Scopes.find()
            return (scopes, f'{how}; instead {why}') if scopes is not None else (None, f'{how}; {why}')
        parents = []
        for controller in want:
            path = next((p for h, c, p in lines if controller in c.split(',')), None)
            if path is not None and (fs / controller).is_dir():
                parents.append((controller, fs / controller / path.lstrip('/')))
            elif controller in need:
                return None, f'cgroup v1 without a {controller} hierarchy'
        return _writable(parents, need)

    def make(self, run_id: str, memory: int, processes: int, cpus: float) -> RunCgroup | None:
        """A cgroup per run with its limits, or None (logged) when the kernel refuses one."""
        name = f'rosgate-{os.getpid()}-{run_id}'
        made: list[Path] = []
        try:
            for controller, parent in self.parents:
                made.append(parent / name)
                made[-1].mkdir()
                for file, value, needed in _limits(controller, memory, processes, cpus):
                    try:
                        (made[-1] / file).write_text(value)
                    except OSError:
                        if needed:
                            raise
        except OSError as e:
            log.warning('run cgroup %s not made (%s): the run has its rlimits only', name, e)
            RunCgroup(tuple(d for d in made if d.exists())).remove()
            return None
        return RunCgroup(tuple(made))


    @property
    def kind(self) -> str:
        return 'cgroup v2' if self.parents[0][0] == 'v2' else 'cgroup v1'

    @property
    def controllers(self) -> tuple[str, ...]:
        """The controllers each run's cgroup has: memory, pids, cpu, or fewer."""
        return self.v2_controllers if self.parents[0][0] == 'v2' else tuple(c for c, _ in self.parents)

    def sweep(self) -> None:
        """Remove the empty run cgroups of gateways that are gone (killed before they could)."""
        for _, parent in self.parents:
            for d in parent.glob('rosgate-*-r*'):
                pid = d.name.split('-')[1]
                if pid.isdigit() and not Path(f'/proc/{pid}').exists():
                    try:
                        d.rmdir()
                    except OSError:
                        pass


def limits_in_force(cgroups: Cgroups | Scopes | None, how: str, *, memory_mb: int, processes: int, cpus: float,
                    cpu_seconds: int, open_files: int) -> str:
    """The start-up sentence saying exactly which limit holds each run, and by what: a cgroup
    (v1 or v2) or only the rlimits the launcher sets (which always apply as well)."""
    on = cgroups.controllers if cgroups is not None else ()
    kind = cgroups.kind if cgroups is not None else ''
    parts = [
        f'memory {memory_mb} MiB by {kind} memory' if 'memory' in on
        else f'memory: only the {memory_mb} MiB address-space rlimit (RLIMIT_AS)',
        f'processes {processes} by {kind} pids' if 'pids' in on
        else f'processes: only RLIMIT_NPROC {processes}',
        f'CPU {cpus:g} core(s) by {kind} cpu quota' if 'cpu' in on
        else 'CPU: no share limit, only RLIMIT_CPU',
        f'CPU time {cpu_seconds} s by RLIMIT_CPU, open files {open_files} by RLIMIT_NOFILE',
    ]
    return f'run limits: {"; ".join(parts)} ({how if cgroups is not None else f"no run cgroups: {how}"})'


def _limits(controller: str, memory: int, processes: int, cpus: float) -> list[tuple[str, str, bool]]:
    """(file, value, required) for a run cgroup of one v1 controller or of v2. The CPU weight
    stays the default: a run as a whole weighs as much as one process of the machine (a lower one
    starved runs on a loaded machine), and its quota keeps it to ``cpus`` cores."""
    quota = str(max(1000, int(cpus * 100000)))
    return {
        'memory': [('memory.limit_in_bytes', str(memory), True), ('memory.memsw.limit_in_bytes', str(memory), False)],
        'pids': [('pids.max', str(processes), True)],
        'cpu': [('cpu.cfs_period_us', '100000', False), ('cpu.cfs_quota_us', quota, False)],
        'v2': [('memory.max', str(memory), True), ('memory.swap.max', '0', False), ('pids.max', str(processes), True),
               ('cpu.max', f'{quota} 100000', False)],
    }[controller]


LEAF = 'rosgate-gateway'   # the leaf cgroup v2 the gateway moves itself into (see _v2)


def _v2(parent: Path, want, need) -> tuple[Cgroups | None, str]:
    """Run cgroups under the gateway's own cgroup v2. The kernel enables a controller for a
    cgroup's children only while that cgroup holds no process (the "no internal processes" rule:
    writing +memory to cgroup.subtree_control answers EBUSY), and the gateway's own cgroup holds
    the gateway. So, as systemd documents for a delegated cgroup (Delegate=yes), the gateway
    first moves itself into a leaf of its own, ``rosgate-gateway``, then enables the controllers;
    the runs' cgroups are that leaf's siblings. Where the cgroup holds other processes too (a
    login shell's scope), or the controllers were never delegated to it, the sentence says so."""
    available = _read_words(parent / 'cgroup.controllers')
    lacking = [c for c in want if c not in available]
    if [c for c in lacking if c in need]:
        return None, (f'cgroup v2: {" and ".join(lacking)} not delegated to {parent} (start the gateway in a cgroup '
                      'of its own with Delegate=yes, e.g. a systemd service, or systemd-run --scope -p Delegate=yes)')
    moved = ''
    missing = _delegate(parent, [c for c in want if c in available])
    if missing and _busy(parent):
        moved = _into_leaf(parent)
        missing = _delegate(parent, missing) if moved.startswith('moved') else missing
    if [c for c in missing if c in need]:
        why = moved or f'{parent}/cgroup.subtree_control refused them'
        return None, f'cgroup v2: {" and ".join(missing)} not enabled for the runs in {parent} ({why})'
    found, how = _writable([('v2', parent)], need)
    if found is None:
        return None, how
    on = tuple(c for c in want if c not in missing and c not in lacking)
    return Cgroups(found.parents, on), (f'cgroup v2 limits ({", ".join(on)}) in {parent}'
                                        + (f'; the gateway {moved}' if moved else ''))


def _read_words(path: Path) -> list[str]:
    try:
        return path.read_text().split()
    except OSError:
        return []


def _busy(parent: Path) -> bool:
    """Whether the cgroup holds processes (then the kernel refuses to enable controllers)."""
    return bool(_read_words(parent / 'cgroup.procs'))


def _into_leaf(parent: Path) -> str:
    """Move this process into parent/rosgate-gateway, so that parent holds no process of ours; a
    sentence saying what was done or why not."""
    others = [p for p in _read_words(parent / 'cgroup.procs') if p != str(os.getpid())]
    if others:
        return f'{parent} holds {len(others)} other process(es), so its controllers cannot be enabled'
    leaf = parent / LEAF
    try:
        leaf.mkdir(exist_ok=True)
        (leaf / 'cgroup.procs').write_text(str(os.getpid()))
    except OSError as e:
        return f'could not move itself into {leaf} ({e.strerror})'
    return f'moved itself into {leaf} first'


def _delegate(parent: Path, controllers) -> list[str]:
    """Enable controllers for the children of a v2 cgroup; those that stay off."""
    try:
        on = (parent / 'cgroup.subtree_control').read_text().split()
    except OSError:
        return list(controllers)
    for c in controllers:
        if c not in on:
            try:
                (parent / 'cgroup.subtree_control').write_text(f'+{c}')
                on.append(c)
            except OSError:
                pass
    return [c for c in controllers if c not in on]


def _writable(parents: list[tuple[str, Path]], need=('memory', 'pids')) -> tuple[Cgroups | None, str]:
    """Those parents in which the gateway can make a cgroup (cpu is optional), with a sentence."""
    probe = f'rosgate-probe-{os.getpid()}'
    usable = []
    for controller, parent in parents:
        try:
            (parent / probe).mkdir()
            (parent / probe).rmdir()
            usable.append((controller, parent))
        except OSError as e:
            if controller in need or controller == 'v2':
                return None, f'cannot make cgroups in {parent} ({e.strerror})'
    if not usable:
        return None, 'no cgroup hierarchy to make run cgroups in'
    kinds = ', '.join(c for c, _ in usable)
    where = ', '.join(str(p) for _, p in usable)
    return Cgroups(tuple(usable)), f'cgroup v1 limits ({kinds}) in {where}'


SYSTEMD = Path('/run/systemd/system')   # present when systemd is the init (what sd_booted checks)
SCOPE_CHECK = ('d=/sys/fs/cgroup$(sed -n "s/^0:://p" /proc/self/cgroup); '
               'for f in memory.max pids.max cpu.max; do echo "$f $(cat "$d/$f" 2>/dev/null)"; done')


@dataclass(frozen=True)
class Scopes:
    """Run limits by systemd where the gateway's own cgroup v2 cannot have run cgroups (a login
    shell's scope holds the shell too): each run starts in a transient scope unit made by
    ``systemd-run --scope -p MemoryMax= -p TasksMax= -p CPUQuota=``, systemd's documented way to
    give a command resource limits (systemd owns the cgroup tree and enables the controllers on
    the way down). As root the system manager makes them, else the user's (``--user``)."""
    command: tuple[str, ...]                  # systemd-run [--user]
    controllers: tuple[str, ...]              # those the start-up probe saw in force
    kind = 'systemd scope'

    @classmethod
    def find(cls, systemd: Path = SYSTEMD) -> tuple[Scopes | None, str]:
        """Scopes where systemd runs and a probe scope shows its limits in its own cgroup files."""
        if not systemd.is_dir():
            return None, f'systemd is not running here ({systemd} is missing)'
        exe = shutil.which('systemd-run')
        if exe is None:
            return None, 'systemd-run is not installed'
        command = (exe,) if os.geteuid() == 0 else (exe, '--user')
        probe = [*command, *_scope_options('rosgate-probe', 64 * 2**20, 16, 1.0), '/bin/sh', '-c', SCOPE_CHECK]
        try:
            done = subprocess.run(probe, capture_output=True, text=True, timeout=30, stdin=subprocess.DEVNULL)
        except (OSError, subprocess.SubprocessError) as e:
            return None, f'systemd-run does not run: {e}'
        if done.returncode != 0:
            return None, f'systemd-run --scope refused: {done.stderr.strip()[-300:]}'
        seen = dict(line.split(' ', 1) for line in done.stdout.splitlines() if ' ' in line)
        expected = {'memory': ('memory.max', str(64 * 2**20)), 'pids': ('pids.max', '16'),
                    'cpu': ('cpu.max', '100000 100000')}
        on = tuple(c for c, (f, v) in expected.items() if seen.get(f, '').strip() == v)
        if 'memory' not in on or 'pids' not in on:
            return None, f'systemd-run scopes here do not get memory and pids limits (saw {seen})'
        return cls(command, on), f'a systemd scope per run ({" ".join(command)} --scope), checked at start'

    def make(self, run_id: str, memory: int, processes: int, cpus: float) -> RunScope:
        return RunScope((*self.command, *_scope_options(f'rosgate-{os.getpid()}-{run_id}', memory, processes, cpus)))

    def sweep(self) -> None:
        """Nothing to sweep: systemd removes a scope once its processes are gone (--collect)."""


def _scope_options(unit: str, memory: int, processes: int, cpus: float) -> list[str]:
    return ['--scope', '--quiet', '--collect', f'--unit={unit}', '-p', f'MemoryMax={memory}', '-p', 'MemorySwapMax=0',
            '-p', f'TasksMax={processes}', '-p', f'CPUQuota={max(1, round(cpus * 100))}%', '--']


@dataclass(frozen=True)
class RunScope:
    """A run's systemd scope: systemd-run execs the run's command in it (same pid), and removes
    it when the run ends."""
    prefix: tuple[str, ...]
    dirs: tuple[Path, ...] = ()

    def join(self, argv: list[str]) -> list[str]:
        return [*self.prefix, *argv]

    def oom_killed(self) -> bool:
        return False   # systemd stops and collects the scope: a kill reads as SIGKILL, perhaps memory

    def remove(self) -> bool:
        return True


@dataclass(frozen=True)
class RunCgroup:
    dirs: tuple[Path, ...]

    def join(self, argv: list[str]) -> list[str]:
        """``argv`` started by a shell that first moves itself into the cgroup: bwrap and all it
        starts are in it from their first instruction."""
        return ['/bin/sh', '-c', JOIN, 'rosgate-run', *(str(d / 'cgroup.procs') for d in self.dirs), '--', *argv]

    def oom_killed(self) -> bool:
        """Whether the kernel killed a process of the run for its memory limit."""
        for d in self.dirs:
            for name in ('memory.events', 'memory.oom_control'):
                try:
                    text = (d / name).read_text()
                except OSError:
                    continue
                counts = dict(line.split()[:2] for line in text.splitlines() if len(line.split()) >= 2)
                if int(counts.get('oom_kill', 0)) > 0:
                    return True
        return False

    def remove(self) -> bool:
        """Remove the directories (each once it holds no process); True when all are gone."""
        gone = True
        for d in self.dirs:
            try:
                d.rmdir()
            except FileNotFoundError:
                pass
            except OSError:
                gone = False
        return gone
