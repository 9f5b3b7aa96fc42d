"""What each test costs in CPU-seconds, measured on the test process's whole process tree (gateways,
Chromium, Firefox, WebKit, node, PostgreSQL, nginx, runs), with the gateways and browsers it
started: ``pytest --cost DIR`` (every xdist process writes DIR/cost-<worker>.jsonl, one line per
test; ``python -m tests.bench suite DIR`` sums them per file). Off unless asked.

CPU time, not wall time: on a busy 2-core machine a test's wall time says how busy the others were,
its CPU-seconds what it asked of the machine. The tree's total is exact for every process reaped
inside the tree (a process's own time plus its reaped children's, /proc/PID/stat fields 14-17: a
child's time moves into its parent's at its reaping); a process whose parent left before it
(reparented to init: a daemonised PostgreSQL) is followed by its pid and counted up to its last
sample. A thread samples the tree every 0.2 s for the split by kind (a process's kind is read from
its command line, else its parent's) and the starts; the totals are read again at every test's
end. What a process reaped outside the tree (or by a parent that ignores SIGCHLD) did after its last
look is missed: at most 0.2 s of it. A parent's children's time that nobody was seen doing (a child
that lived less than a look) goes to the kind of the children that left, else to the parent's."""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

import pytest

TICK = os.sysconf('SC_CLK_TCK')
INTERVAL = 0.2   # s between the sampler's looks


def kind_of(cmdline: list[str]) -> str | None:
    """A process's kind from its command line, None when it is its parent's."""
    if cmdline and os.path.basename(cmdline[0]) in ('sh', 'dash', 'bash'):   # a launcher script
        cmdline = cmdline[1:]
    if not cmdline:
        return None
    exe = os.path.basename(cmdline[0])
    line = ' '.join(cmdline)
    if exe.startswith('python') and ('-m gateway' in line or '-mgateway' in line) or any(
            os.path.basename(a) == 'rosgate' for a in cmdline[:2]):
        return 'gateway'
    if 'chrom' in exe or 'headless_shell' in exe:
        return 'chromium'
    if 'firefox' in exe or exe == 'Web Content' or 'firefox' in line.split(' ', 1)[0]:
        return 'firefox'
    if 'WebKit' in exe or 'MiniBrowser' in exe or 'webkit' in line.split(' ', 1)[0].lower():
        return 'webkit'
    if exe == 'node':
        return 'playwright' if 'playwright' in line else 'node'
    if exe in ('postgres', 'postmaster', 'pg_ctl', 'initdb'):
        return 'postgres'
    if exe == 'nginx':
        return 'nginx'
    if exe.startswith('Xvfb'):
        return 'xvfb'
    if exe in ('pip', 'pip3') or ' -m pip ' in line or exe in ('colcon', 'cmake', 'make', 'cc1', 'cc1plus', 'ld'):
        return 'build'
    return None


def start_of(kind: str, cmdline: list[str], parent_kind: str | None) -> bool:
    """Is this the first process of a gateway, a browser (not a renderer, a helper, a content
    process), a PostgreSQL server (not initdb's), an nginx or an Xvfb?"""
    if kind == parent_kind or not cmdline:
        return kind == 'postgres' and _postmaster(cmdline)
    line = ' '.join(cmdline)
    if kind == 'chromium':
        return '--type=' not in line
    if kind == 'firefox':
        return '-contentproc' not in line and os.path.basename(cmdline[0]) != 'Web Content'
    if kind == 'webkit':
        return 'MiniBrowser' in line
    if kind == 'postgres':
        return _postmaster(cmdline)
    return kind in ('gateway', 'nginx', 'xvfb')


def _postmaster(cmdline: list[str]) -> bool:
    return (bool(cmdline) and os.path.basename(cmdline[0]) == 'postgres' and '-D' in cmdline
            and '--boot' not in cmdline and '--single' not in cmdline)


class Proc:
    __slots__ = ('pid', 'start', 'ppid', 'kind', 'own', 'children', 'adopted')

    def __init__(self, pid, start, ppid, kind, own, children):
        self.pid, self.start, self.ppid, self.kind = pid, start, ppid, kind
        self.own, self.children, self.adopted = own, children, False


def _stat(pid: int):
    """(ppid, starttime, own seconds, reaped children's seconds) of a process, or None if it left."""
    try:
        with open(f'/proc/{pid}/stat', 'rb') as f:
            data = f.read()
    except OSError:
        return None
    fields = data[data.rindex(b')') + 2:].split()
    # fields[0] is the state (stat field 3): ppid 4, utime 14, stime 15, cutime 16, cstime 17, starttime 22
    return (int(fields[1]), int(fields[19]), (int(fields[11]) + int(fields[12])) / TICK,
            (int(fields[13]) + int(fields[14])) / TICK)


def _cmdline(pid: int) -> list[str]:
    try:
        with open(f'/proc/{pid}/cmdline', 'rb') as f:
            return [a.decode(errors='replace') for a in f.read().split(b'\0') if a]
    except OSError:
        return []


def _children(pid: int) -> list[int]:
    found = []
    try:
        for task in os.listdir(f'/proc/{pid}/task'):
            try:
                with open(f'/proc/{pid}/task/{task}/children') as f:
                    found += [int(c) for c in f.read().split()]
            except OSError:
                pass
    except OSError:
        pass
    return found


class Tree:
    """The CPU-seconds of a process and everything below it, by kind, and the gateways and browsers
    started under it."""

    def __init__(self, root: int, root_kind: str = 'pytest'):
        self.root, self.root_kind = root, root_kind
        self.procs: dict[int, Proc] = {}
        self.by_kind: dict[str, float] = {}
        self.total = 0.0            # the tree's CPU-seconds so far (since the Tree was made)
        self.started: dict[str, int] = {}   # 'gateway', 'chromium', 'firefox', 'webkit', 'postgres' ...
        self.lock = threading.Lock()
        self.sample()
        self.total, self.by_kind, self.started = 0.0, {}, {}

    def _add(self, kind: str, seconds: float) -> None:
        if seconds:
            self.by_kind[kind] = self.by_kind.get(kind, 0.0) + seconds
            self.total += seconds

    def sample(self) -> None:
        with self.lock:
            self._sample()

    def _sample(self) -> None:
        seen: dict[int, tuple] = {}
        todo = [self.root] + [p.pid for p in self.procs.values() if p.adopted]
        while todo:
            pid = todo.pop()
            if pid in seen:
                continue
            st = _stat(pid)
            if st is None:
                continue
            seen[pid] = st
            todo += _children(pid)
        old = self.procs
        new: dict[int, Proc] = {}
        gone = {pid: p for pid, p in old.items() if pid not in seen or seen[pid][1] != p.start}
        # the processes that left, by the parent that reaped them: their time (and that of their own
        # children that left with them) moved into its cutime, and was counted up to their last look
        left_under: dict[int, list[Proc]] = {}
        for p in gone.values():
            left_under.setdefault(p.ppid, []).append(p)

        def counted(p: Proc) -> float:
            return p.own + p.children + sum(counted(c) for c in left_under.get(p.pid, ()))
        for pid, (ppid, start, own, children) in seen.items():
            p = old.get(pid)
            if p is not None and p.start == start:
                self._add(p.kind, own - p.own)
                extra = children - p.children
                left = left_under.pop(pid, [])
                # already counted as theirs: the whole subtree that left, if it left through this
                # parent's waits; if that is more than came in, part of it left elsewhere (orphaned,
                # reaped by init) and what it did after its last look is lost
                extra -= sum(counted(c) for c in left)
                self._add(left[0].kind if left else p.kind, max(extra, 0.0))
                p.own, p.children, p.ppid = own, children, ppid
                p.adopted = p.adopted or (pid != self.root and ppid not in seen)
                new[pid] = p
            else:
                parent = new.get(ppid) or old.get(ppid)
                cmd = _cmdline(pid)
                if pid == self.root:
                    kind = self.root_kind
                else:   # a process of the test's own (a script, a tool) is a 'child', not the test process
                    kind = kind_of(cmd) or (parent.kind if parent and parent.pid != self.root else 'child')
                p = Proc(pid, start, ppid, kind, own, children)
                p.adopted = pid != self.root and ppid not in seen
                new[pid] = p
                self._add(kind, own + children)
                if pid != self.root and start_of(kind, cmd, parent.kind if parent else None):
                    self.started[kind] = self.started.get(kind, 0) + 1
        # children that left under a parent that also left, or adopted ones reaped by init: their
        # time leaves the tree with them; what was last seen was counted, the rest is lost
        self.procs = new

    def snapshot(self) -> tuple[float, dict, dict]:
        with self.lock:
            self._sample()
            return self.total, dict(self.by_kind), dict(self.started)


def _loadavg() -> list[float]:
    with open('/proc/loadavg') as f:
        return [float(x) for x in f.read().split()[:3]]


class CostRecorder:
    def __init__(self, out: Path, worker: str):
        self.out = out
        out.mkdir(parents=True, exist_ok=True)
        self.file = open(out / f'cost-{worker}.jsonl', 'a')
        self.tree = Tree(os.getpid())
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name='cost-sampler', daemon=True)
        self.thread.start()
        self.last = self.tree.snapshot()
        self.t0 = time.monotonic()

    def _run(self):
        while not self.stop.wait(INTERVAL):
            try:
                self.tree.sample()
            except Exception:   # a sampler must never end a test run
                pass

    def record(self, nodeid: str, outcome: str, load: list[float]) -> None:
        now = self.tree.snapshot()
        t1 = time.monotonic()
        total, kinds, started = now
        total0, kinds0, started0 = self.last
        row = {'test': nodeid, 'file': nodeid.split('::', 1)[0], 'outcome': outcome,
               'wall': round(t1 - self.t0, 3), 'cpu': round(total - total0, 3),
               'kinds': {k: round(v - kinds0.get(k, 0.0), 3) for k, v in kinds.items()
                         if abs(v - kinds0.get(k, 0.0)) > 0.0005},
               'started': {k: v - started0.get(k, 0) for k, v in started.items() if v - started0.get(k, 0)},
               'load': load, 'load_end': _loadavg()}
        self.file.write(json.dumps(row) + '\n')
        self.file.flush()
        self.last, self.t0 = now, t1

    def close(self):
        self.stop.set()
        self.thread.join(2)
        self.file.close()


def pytest_addoption(parser):
    parser.addoption('--cost', metavar='DIR', default=None,
                     help='write each test\'s CPU-seconds (its process tree\'s, by kind) and the gateways and '
                          'browsers it started to DIR/cost-<worker>.jsonl (python -m tests.bench suite DIR)')


_recorder: CostRecorder | None = None


def pytest_configure(config):
    global _recorder
    out = config.getoption('--cost', None)
    if not out or getattr(config.option, 'numprocesses', None) and not hasattr(config, 'workerinput'):
        return   # the xdist controller runs no tests: its workers record
    worker = getattr(config, 'workerinput', {}).get('workerid', 'main')
    _recorder = CostRecorder(Path(out), worker)


def pytest_unconfigure(config):
    global _recorder
    if _recorder is not None:
        _recorder.close()
        _recorder = None


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    if _recorder is None:
        yield
        return
    load = _loadavg()
    outcomes: list[str] = []
    item.stash[_OUTCOMES] = outcomes
    yield
    failed = [o for o in outcomes if o != 'passed']
    _recorder.record(item.nodeid, failed[0] if failed else 'passed', load)


_OUTCOMES = pytest.StashKey[list]()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    outcomes = item.stash.get(_OUTCOMES, None)
    if outcomes is not None and (report.when == 'call' or report.outcome != 'passed'):
        outcomes.append(report.outcome if report.when == 'call' else f'{report.when} {report.outcome}')
