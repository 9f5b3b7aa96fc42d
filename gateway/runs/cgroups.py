"""Cgroup limits for a robot-side run, where this machine lets the gateway make cgroups: a cgroup v2
subtree delegated to the gateway (or one it moves itself into a leaf of), a writable v1
hierarchy, or a systemd scope per run (``systemd-run --scope``). ``Cgroups.find`` and
``Scopes.find`` say which, and why not; ``limits_in_force`` is the start-up log's line.

Memory, processes and a CPU share per run; the rlimits the launcher sets (``launcher.py``) hold
where none of these is available.
"""

from __future__ import annotations

import logging
import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger('rosgate.sandbox')

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
