"""Servers under test: starting rosgate and the ceiling, and reading a pid's CPU and RSS."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
WS_URL = re.compile(r"ws://[^\s/]+:\d+/")


def end(proc: subprocess.Popen, sig: int = signal.SIGTERM, timeout: float = 5) -> int | None:
    """Stop a process: ``sig``, then a kill if it has not ended within ``timeout``; its exit code."""
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout)
    return proc.returncode


@dataclass
class Target:
    name: str
    url: str
    pid: int | None = None
    kind: str = "rosbridge"  # or "ceiling": gets preloaded frames
    process: subprocess.Popen | None = field(default=None, repr=False)
    log: Path | None = None
    argv: list[str] = field(default_factory=list)

    def stop(self) -> None:
        if self.process is not None:
            end(self.process)


def _start(name: str, kind: str, argv: list[str], timeout: float = 30.0, checkout: Path = REPO) -> Target:
    """A server started in ``checkout`` (its code first on the path: another checkout's rosgate
    runs with this interpreter's libraries)."""
    log = Path(tempfile.mkstemp(prefix=f"bench-{name}-", suffix=".log")[1])
    err = open(log, "wb")
    env = None
    if Path(checkout).resolve() != REPO:
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(checkout), os.environ.get("PYTHONPATH")])))
    proc = subprocess.Popen(argv, cwd=checkout, stdout=subprocess.PIPE, stderr=err, text=True, env=env)
    err.close()
    lines: list[str] = []
    got = threading.Event()

    def drain() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:  # keep the pipe empty for the server's lifetime
            if not got.is_set():
                lines.append(line)
                if WS_URL.search(line):
                    got.set()
        got.set()

    threading.Thread(target=drain, daemon=True).start()
    got.wait(timeout)
    match = WS_URL.search("".join(lines))
    if match is None:
        proc.kill()
        proc.wait(5)
        raise RuntimeError(
            f"{name} did not print its websocket address within {timeout:.0f} s: "
            f"{''.join(lines)!r}; stderr in {log}: {log.read_text()[-2000:]}"
        )
    return Target(name=name, url=match.group(0), pid=proc.pid, kind=kind, process=proc, log=log,
                  argv=argv[1:])


def start_ceiling(malloc_tune: bool = True) -> Target:
    argv = [sys.executable, "-m", "tests.bench.ceiling", "--port", "0"]
    return _start("ceiling", "ceiling", argv + ([] if malloc_tune else ["--no-malloc-tune"]))


def default_rosgate_args() -> list[str]:
    """The sim backend, no robots when the CLI offers that, and a scratch program library."""
    help_text = subprocess.run([sys.executable, "-m", "gateway", "--help"], cwd=REPO,
                               capture_output=True, text=True, timeout=60).stdout
    args = []
    if "--backend" in help_text:
        args += ["--backend", "sim"]
    if "--robot" in help_text:
        args += ["--robot", "none"]
    if "--programs-dir" in help_text:
        args += ["--programs-dir", tempfile.mkdtemp(prefix="bench-programs-")]
    return args


def start_rosgate(extra_args: list[str] | None = None, checkout: Path = REPO, name: str = "rosgate") -> Target:
    """rosgate on the sim; from another checkout (``--baseline``) with that checkout's venv when it
    has one."""
    if extra_args is None:
        extra_args = default_rosgate_args()
    python = Path(checkout) / ".venv" / "bin" / "python"
    python = str(python) if Path(checkout).resolve() != REPO and python.exists() else sys.executable
    argv = [python, "-m", "gateway", "--port", "0", "--address", "127.0.0.1", *extra_args]
    return _start(name, "rosbridge", argv, checkout=checkout)


def rosgate_available() -> bool:
    return (REPO / "gateway" / "__main__.py").exists()


class ProcMeter:
    """CPU seconds and RSS of one process, read from /proc.

    CPU comes from the per-thread schedstat (nanoseconds) when the set of threads
    is the same at both ends of a window, else from utime+stime (10 ms ticks),
    which also counts threads that ended during the window.
    """

    TICK = os.sysconf("SC_CLK_TCK")

    def __init__(self, pid: int | None) -> None:
        self.pid = pid

    def sample(self) -> tuple[dict[str, int], float] | None:
        if self.pid is None:
            return None
        try:
            task_dir = f"/proc/{self.pid}/task"
            threads = {}
            for tid in os.listdir(task_dir):
                try:
                    with open(f"{task_dir}/{tid}/schedstat") as f:
                        threads[tid] = int(f.read().split()[0])
                except (OSError, ValueError, IndexError):
                    pass
            with open(f"/proc/{self.pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            ticks = (int(fields[11]) + int(fields[12])) / self.TICK
            return threads, ticks
        except OSError:
            return None

    @staticmethod
    def cpu_between(start, end) -> float | None:
        if start is None or end is None:
            return None
        threads0, ticks0 = start
        threads1, ticks1 = end
        if threads0 and threads0.keys() == threads1.keys():
            return sum(threads1.values()) / 1e9 - sum(threads0.values()) / 1e9
        return ticks1 - ticks0

    def rss_bytes(self) -> int | None:
        if self.pid is None:
            return None
        try:
            with open(f"/proc/{self.pid}/status") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1]) * 1024
        except OSError:
            return None
        return None


def machine_busy_s() -> float:
    """CPU seconds all cores spent busy since boot (/proc/stat)."""
    with open("/proc/stat") as f:
        fields = [int(v) for v in f.readline().split()[1:]]
    idle = fields[3] + fields[4]  # idle, iowait
    return (sum(fields[:8]) - idle) / ProcMeter.TICK


class Window:
    """Elapsed time, server CPU and this process's CPU over one measurement window.

    `other_cpu_pct` is what the rest of the machine used meanwhile (100 = one
    core): a busy neighbour makes figures of the same run incomparable.
    """

    def __init__(self, meter: ProcMeter) -> None:
        self.meter = meter
        self.start()

    def start(self) -> None:
        self.t0 = time.monotonic()
        self.client0 = time.process_time()
        self.server0 = self.meter.sample()
        self.busy0 = machine_busy_s()

    def stop(self, extra_client_cpu: float = 0.0) -> dict[str, float | None]:
        elapsed = time.monotonic() - self.t0
        server = ProcMeter.cpu_between(self.server0, self.meter.sample())
        client = time.process_time() - self.client0 + extra_client_cpu
        other = machine_busy_s() - self.busy0 - client - (server or 0.0)
        return {
            "elapsed_s": elapsed,
            "server_cpu_s": server,
            "server_cpu_pct": None if server is None else 100 * server / elapsed,
            "client_cpu_pct": 100 * client / elapsed,
            "other_cpu_pct": max(0.0, 100 * other / elapsed),
        }
