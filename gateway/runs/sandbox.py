"""The box a robot-side run lives in: bubblewrap (``bwrap``) namespaces and a read-only view of the
interpreter (its cgroup limits: ``cgroups.py``).

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

import fcntl
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
import tempfile
import time
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


# --- the gateway's folder of box files (its unix socket, staged views) ------------------------------

HOME_PREFIX = 'rosgate-box-'
LOCK = '.lock'           # in the folder: flock'ed by its gateway as long as it lives
UNLOCKED_STALE = 86400   # s: a folder with no lock file (an older gateway's) is left this long


def make_home() -> tuple[Path, int]:
    """A fresh folder in the temporary directory for this gateway's box files, and the descriptor of
    its lock file, flock'ed as long as the gateway lives (kept open; the kernel lets go when the
    process dies, however it dies). Folders of gateways that are gone are swept first. A PID in a
    folder's name was the old test, and a gateway in another PID namespace on the same /tmp found
    none of its neighbour's PIDs and deleted its live folder (its runs then failed with exit 125,
    "mount point does not exist"); a lock is the same lock in every namespace."""
    sweep_homes()
    home = Path(tempfile.mkdtemp(prefix=f'{HOME_PREFIX}{os.getpid()}-'))
    fd = os.open(home / f'{LOCK}.new', os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)    # locked before any sweep can see it by its name
    os.rename(home / f'{LOCK}.new', home / LOCK)
    return home, fd


def sweep_homes(folder: Path | None = None, now: float | None = None) -> list[Path]:
    """Remove the box folders of gateways that are gone: those whose lock nobody holds (an older
    gateway's folder without a lock file, once a day old). The folders removed."""
    gone = []
    now = time.time() if now is None else now
    for d in Path(folder or tempfile.gettempdir()).glob(f'{HOME_PREFIX}*'):
        try:
            fd = os.open(d / LOCK, os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC)
        except FileNotFoundError:
            try:
                if d.is_dir() and not d.is_symlink() and now - d.stat().st_mtime > UNLOCKED_STALE \
                        and not (d / f'{LOCK}.new').exists():
                    shutil.rmtree(d, ignore_errors=True)
                    gone.append(d)
            except OSError:
                pass
            continue
        except OSError:
            continue              # not ours to open (another user's gateway): not ours to remove
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            shutil.rmtree(d, ignore_errors=True)      # removed while the lock is ours
            gone.append(d)
        except OSError:
            pass                  # held: a live gateway's
        finally:
            os.close(fd)
    return gone

