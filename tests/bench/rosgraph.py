"""The ROS side of `--backend rclpy`: a loopback-only namespace, the servers and the rclpy nodes.

Everything runs with the ROS environment's Python (`.venv-ros`): rosgate as
`python -m gateway --backend rclpy`, the Rust rosbridge server on the same wheels (when
`rosbridge-server-rs` is installed there and `../shared/bench/rosbridge_rs.sh` exists), and
the plain rclpy nodes of `rosnodes.py`. The harness itself and its websocket clients stay in
the project's environment.
"""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from .servers import REPO, Target, _start, end

ROS_VENV = REPO / ".venv-ros"
ROS_PYTHON_ENV = "ROSGATE_BENCH_ROS_PYTHON"  # set by --ros-python; children inherit it
# shared/ beside the checkout (or beside the folder of worktrees it is in)
RUST_SCRIPT = next((p for p in (REPO.parent / "shared" / "bench" / "rosbridge_rs.sh",
                                REPO.parent.parent / "shared" / "bench" / "rosbridge_rs.sh") if p.exists()),
                   REPO.parent / "shared" / "bench" / "rosbridge_rs.sh")
NETNS_MARK = "ROSGATE_BENCH_NETNS"


def ros_python() -> Path:
    return Path(os.environ.get(ROS_PYTHON_ENV) or ROS_VENV / "bin" / "python")


def isolated() -> bool:
    """Whether this process's network namespace has no interface but loopback."""
    try:
        with open("/proc/self/net/dev") as f:
            names = [line.split(":", 1)[0].strip() for line in f.readlines()[2:]]
    except OSError:
        return False
    return names == ["lo"]


def reexec_isolated(argv: list[str], module: str = "tests.bench") -> None:
    """Run this harness (or another module of it) again inside a fresh loopback-only network
    namespace (never returns)."""
    if os.environ.get(NETNS_MARK):
        raise SystemExit("still not isolated after unshare: the namespace has more than loopback")
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        raise SystemExit("--backend rclpy needs unshare (util-linux) and ip (iproute2) "
                         "for its loopback-only network namespace")
    env = dict(os.environ, **{NETNS_MARK: "1"})
    # a DDS domain of our own as well: Fast DDS's shared-memory transport is not namespaced
    env.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 200))
    script = 'ip link set lo up && exec "$0" "$@"'
    os.execvpe("unshare", ["unshare", "-rn", "sh", "-c", script, sys.executable, "-m", module,
                           *argv], env)


def check_ros_env() -> None:
    if shutil.which(str(ros_python())) is None:
        raise SystemExit(f"--backend rclpy needs {ros_python()}: make .venv-ros/.installed, "
                         "or --ros-python with a Python that has rclpy")


class Proc:
    """A `rosnodes.py` process: stdout lines are JSON, stderr goes to a log file."""

    def __init__(self, role: str, *args: str, timeout: float = 30.0) -> None:
        self.role = role
        self.log = Path(tempfile.mkstemp(prefix=f"bench-ros-{role}-", suffix=".log")[1])
        with open(self.log, "wb") as err:
            self.process = subprocess.Popen(
                [str(ros_python()), "-m", "tests.bench.rosnodes", role, *args], cwd=REPO,
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=err, text=True, bufsize=1)
        self.pid = self.process.pid
        self._lock = threading.Lock()
        try:
            self._read(timeout)
        except BaseException:
            self.stop()
            raise

    def _read(self, timeout: float) -> dict:
        """One JSON line from stdout within `timeout` s (read in a thread: the pipe blocks)."""
        box: list = []
        reader = threading.Thread(target=lambda: box.append(self.process.stdout.readline()), daemon=True)
        reader.start()
        reader.join(timeout)
        if not box or not box[0]:
            self.stop()
            raise RuntimeError(f"rclpy {self.role} node: no answer within {timeout:.0f} s; "
                               f"log {self.log}: {self.log.read_text()[-1500:]}")
        return json.loads(box[0])

    def ask(self, command: dict | str, timeout: float) -> dict:
        with self._lock:
            line = command if isinstance(command, str) else json.dumps(command)
            self.process.stdin.write(line + "\n")
            self.process.stdin.flush()
            return self._read(timeout)

    async def ask_async(self, command: dict | str, timeout: float) -> dict:
        return await asyncio.to_thread(self.ask, command, timeout)

    def stop(self) -> None:
        proc = self.process
        try:
            proc.stdin.close()  # ends the ceiling's command loop
        except OSError:
            pass
        end(proc, signal.SIGINT)
        try:
            proc.stdout.close()
        except OSError:
            pass


class CeilingTarget(Target):
    """The rclpy ceiling as a target of the interleaved run: it has a pid but no websocket."""

    node: Proc

    def stop(self) -> None:
        self.node.stop()


def start_rclpy_ceiling() -> CeilingTarget:
    node = Proc("ceiling")
    target = CeilingTarget(name="rclpy", url="", pid=node.pid, kind="rclpy", log=node.log,
                           argv=["-m", "tests.bench.rosnodes", "ceiling"])
    target.node = node
    return target


def start_rosgate_rclpy(extra_args: list[str] | None = None, checkout: Path = REPO,
                        name: str = "rosgate") -> Target:
    """rosgate on rclpy (the ROS environment's Python; from another checkout with ``--baseline``)."""
    programs = tempfile.mkdtemp(prefix="bench-programs-")
    args = extra_args if extra_args is not None else ["--backend", "rclpy", "--programs-dir", programs]
    argv = [str(ros_python()), "-m", "gateway", "--port", "0", "--address", "127.0.0.1", *args]
    return _start(name, "rosbridge", argv, checkout=checkout)


def rust_unavailable() -> str | None:
    """Why the Rust server's column is skipped, or None when it can run."""
    if not RUST_SCRIPT.exists():
        return f"no {RUST_SCRIPT} on this machine"
    if not list(ROS_VENV.glob("lib/python3.*/site-packages/rosbridge_server_rs")):
        return f"rosbridge-server-rs is not installed in {ROS_VENV} (make {ROS_VENV}/.installed-bench)"
    return None


def versions() -> dict[str, str]:
    """Versions of the ROS packages under test, as the ROS environment's pip knows them."""
    code = ("import importlib.metadata as m, json, os\n"
            "out = {'rmw': os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp (default)')}\n"
            "for p in ('ros-rclpy', 'ros-rmw-fastrtps-cpp', 'rosbridge-server-rs'):\n"
            "    try: out[p] = m.version(p)\n"
            "    except m.PackageNotFoundError: pass\n"
            "print(json.dumps(out))")
    try:
        done = subprocess.run([str(ros_python()), "-c", code], capture_output=True, text=True, timeout=60)
        return json.loads(done.stdout)
    except (OSError, ValueError, subprocess.TimeoutExpired):
        return {}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_rust(timeout: float = 30.0) -> Target:
    """rosbridge_server_rs on 127.0.0.1 (it prints no address: wait until the port accepts)."""
    port = free_port()
    log = Path(tempfile.mkstemp(prefix="bench-rust-", suffix=".log")[1])
    argv = ["bash", str(RUST_SCRIPT), str(ROS_VENV), str(port)]
    with open(log, "wb") as out:
        proc = subprocess.Popen(argv, cwd=REPO, stdout=out, stderr=subprocess.STDOUT)
    target = Target(name="rust", url=f"ws://127.0.0.1:{port}/", pid=proc.pid, process=proc, log=log,
                    argv=argv[1:])
    deadline = time.monotonic() + timeout
    while True:
        if proc.poll() is not None:
            raise RuntimeError(f"rosbridge_server_rs exited with {proc.returncode}: {log.read_text()[-1500:]}")
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return target
        except OSError:
            if time.monotonic() > deadline:
                target.stop()
                raise RuntimeError(f"rosbridge_server_rs did not listen on {port} within {timeout:.0f} s")
            time.sleep(0.1)


class ImageNode:
    """A 640x480 rgb8 camera node on its own topic, for one measured point."""

    def __init__(self, topic: str, rate: float) -> None:
        self.topic = topic
        self.node = Proc("image", "--topic", topic, "--rate", str(rate))

    async def count(self) -> int:
        return (await self.sample())[0]

    async def sample(self) -> tuple[int, float]:
        """(images published so far, the camera's CLOCK_MONOTONIC time then)."""
        reply = await self.node.ask_async("count", 10)
        return reply["count"], reply["t"]

    def stop(self) -> None:
        self.node.stop()


class RosGraph:
    """The long-running ROS end of the run: the service server node."""

    def __init__(self) -> None:
        self.server = Proc("serve")

    def stop(self) -> None:
        self.server.stop()
