"""Command line and orchestration of the benchmark.

    .venv/bin/python -m tests.bench [--quick] [--out FILE] [--target ws://HOST:PORT --server-pid PID]...
    .venv/bin/python -m tests.bench --backend rclpy [--quick]

By default it starts the ceiling server and rosgate (sim backend), runs every
scenario against both, repeat by repeat, and prints each rosgate figure next
to the ceiling's and as a ratio of it. With `--backend rclpy` it re-runs itself
in a loopback-only network namespace and measures rosgate on rclpy, the Rust
rosbridge server (when installed) and plain rclpy nodes (the rclpy ceiling).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import tornado
import websockets

from . import payloads, report, rosgraph, rosplan
from .ceiling import tune_malloc
from .fanout import fanout
from .profile import PySpy
from .servers import ProcMeter, Target, rosgate_available, start_ceiling, start_rosgate
from .services import services
from .topics import encoding_max, encoding_rate, slow_consumer, throughput

SCENARIOS = ("throughput", "fanout", "encodings", "services", "slow_consumer")
ROS_SCENARIOS = ("throughput", "fanout", "images", "services", "slow_consumer")
KIB = 1024
BASELINE = "before"   # the target started from --baseline's checkout


@dataclass
class Config:
    repeats: int = 3
    sizes: list[int] = field(default_factory=lambda: [64, KIB, 64 * KIB, KIB * KIB])
    windows: list[int] = field(default_factory=lambda: [1, 32])
    point_s: float = 1.5
    fanout_ns: list[int] = field(default_factory=lambda: [1, 10, 100])
    fanout_rate: float = 10.0
    fanout_size: int = KIB
    fanout_s: float = 2.5
    fanout_procs: int = 2
    malloc_tune: bool = True
    encodings: list[str] = field(default_factory=lambda: ["none", "cbor", "cbor-raw"])
    encoding_window: int = 2
    rate_s: float = 2.0
    concurrency: list[int] = field(default_factory=lambda: [1, 32])
    slow_s: float = 60.0
    scenarios: list[str] = field(default_factory=lambda: list(SCENARIOS))


def quick_config() -> Config:
    return Config(repeats=1, sizes=[64, KIB, 64 * KIB], point_s=0.15, fanout_ns=[1, 10],
                  fanout_rate=20.0, fanout_s=0.3, rate_s=0.3, slow_s=1.5)


def rclpy_config(quick: bool) -> Config:
    """The issue's points: no 1 MiB strings, images from a camera node instead of encodings."""
    cfg = quick_config() if quick else Config()
    cfg.sizes = [64, KIB, 64 * KIB]
    cfg.scenarios = list(ROS_SCENARIOS)
    if quick:  # each image point waits for DDS discovery of a new camera node
        cfg.rate_s, cfg.slow_s = 0.5, 2.0
    return cfg


def size_label(size: int) -> str:
    if size >= KIB * KIB:
        return f"{size // (KIB * KIB)}MiB"
    return f"{size // KIB}KiB" if size >= KIB else f"{size}B"


def shared_points(cfg, scenario: str, run: dict):
    """The points of the scenarios every backend's bench has (throughput, fanout, services,
    slow_consumer), each measured by ``run[scenario]``: (scenario, label, point, run(target),
    repeated?); none for another scenario."""
    if scenario == "throughput":
        for size in cfg.sizes:
            for w in cfg.windows:
                yield (scenario, f"{size_label(size)} W={w}", {"size": size, "window": w},
                       lambda t, s=size, w=w: run[scenario](t, s, w, cfg.point_s), True)
    elif scenario == "fanout":
        for n in cfg.fanout_ns:
            yield (scenario, f"N={n} {cfg.fanout_rate:g}Hz {size_label(cfg.fanout_size)}",
                   {"subscribers": n, "rate": cfg.fanout_rate, "size": cfg.fanout_size},
                   lambda t, n=n: run[scenario](t, n, cfg.fanout_rate, cfg.fanout_size, cfg.fanout_s,
                                                cfg.repeats, cfg.fanout_procs, cfg.malloc_tune), False)
    elif scenario == "services":
        for c in cfg.concurrency:
            yield (scenario, f"C={c}", {"concurrency": c}, lambda t, c=c: run[scenario](t, c, cfg.point_s), True)
    elif scenario == "slow_consumer":
        yield (scenario, f"{cfg.slow_s:g}s", {"duration_s": cfg.slow_s},
               lambda t: run[scenario](t, cfg.slow_s), False)


def plan(cfg: Config):
    """(scenario, label, point, run(target) -> list of runs, repeated?) in order."""
    image, cloud = payloads.image(), payloads.pointcloud()
    sim = {"throughput": throughput, "fanout": fanout, "services": services, "slow_consumer": slow_consumer}
    for scenario in cfg.scenarios:
        yield from shared_points(cfg, scenario, sim)
        if scenario == "encodings":
            for payload in (image, cloud):
                for enc in cfg.encodings:
                    yield (scenario, f"{payload.name} {enc}", {"payload": payload.name, "compression": enc},
                           lambda t, p=payload, e=enc: encoding_max(t, p, e, cfg.encoding_window, cfg.point_s),
                           True)
            for subs, enc in ((0, "none"), (3, "cbor")):
                yield ("encodings_rate", f"{image.name} 30Hz {subs}x{enc if subs else 'pub only'}",
                       {"payload": image.name, "subscribers": subs, "compression": enc, "rate": 30},
                       lambda t, s=subs, e=enc: encoding_rate(t, image, e, s, 30.0, cfg.rate_s), True)


def alive_error(target: Target) -> str | None:
    if target.process is not None and target.process.poll() is not None:
        return f"server exited with code {target.process.returncode}; log {target.log}"
    return None


async def run_point(fn, target: Target, budget: float) -> list[dict]:
    dead = alive_error(target)
    if dead:
        raise RuntimeError(dead)
    result = await asyncio.wait_for(fn(target), budget)
    return result if isinstance(result, list) else [result]


async def idle_cpu(target: Target, seconds: float) -> float | None:
    meter = ProcMeter(target.pid)
    start = meter.sample()
    await asyncio.sleep(seconds)
    cpu = ProcMeter.cpu_between(start, meter.sample())
    return None if cpu is None else 100 * cpu / seconds


async def run_all(cfg: Config, targets: list[Target], log, ros: bool = False) -> dict:
    results: dict[str, list[dict]] = {}
    names = [t.name for t in targets]
    bases = tuple(n for n in ("rust", "rclpy") if n in names) if ros else ("ceiling",)
    current = None
    for scenario, label, point, fn, repeated in (rosplan.plan(cfg) if ros else plan(cfg)):
        if scenario != current and current is not None:
            log(f"\n{report.title(current, ros)}\n{report.table(current, results[current], names)}\n")
        current = scenario
        entry = {"label": label, "point": point, "runs": {n: [] for n in names}, "errors": {}}
        budget = 60 + 3 * max(cfg.point_s, cfg.fanout_s, cfg.rate_s) * cfg.repeats + cfg.slow_s
        for rep in range(cfg.repeats if repeated else 1):
            for target in targets:
                if target.name in entry["errors"]:
                    continue
                started = time.monotonic()
                try:
                    runs = await run_point(fn, target, budget)
                except rosplan.NotApplicable:
                    continue
                except Exception as exc:  # recorded, and the run goes on
                    entry["errors"][target.name] = f"{type(exc).__name__}: {exc}"
                    log(f"  {scenario} {label} {target.name}: {entry['errors'][target.name]}", err=True)
                    continue
                load = loadavg()
                for r in runs:
                    r["load1"] = load   # the machine's 1-minute load average as the point ended
                entry["runs"][target.name].extend(runs)
                first_key = report.COLUMNS[scenario][0][0]
                shown = ", ".join(report.fmt(r.get(first_key)) for r in runs)
                log(f"  {scenario} {label} {target.name} #{rep + 1}: {first_key}={shown} "
                    f"({time.monotonic() - started:.1f} s, load {load:.2f})", err=True)
        report.finish_point(entry, bases or ("ceiling",), BASELINE if BASELINE in names else None)
        results.setdefault(scenario, []).append(entry)
    if current is not None:
        log(f"\n{report.title(current, ros)}\n{report.table(current, results[current], names)}\n")
    return results


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m tests.bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--backend", choices=["sim", "rclpy"], default="sim",
                   help="rosgate's backend; rclpy: rosgate, the Rust server and the rclpy ceiling on the "
                        ".venv-ros wheels, in a loopback-only network namespace (default sim)")
    p.add_argument("--target", action="append", default=[],
                   help="a running rosbridge server, ws://HOST:PORT/; repeatable; "
                        "rosgate is then not started unless --with-rosgate")
    p.add_argument("--target-name", action="append", default=[],
                   help="name of each --target in the tables, in order (default target, target2, ...)")
    p.add_argument("--server-pid", action="append", type=int, default=[],
                   help="pid of each --target, in order, for its CPU and RSS")
    p.add_argument("--with-rosgate", action="store_true", help="start rosgate as well as the --target(s)")
    p.add_argument("--baseline", metavar="DIR", type=Path,
                   help="also start the rosgate of another checkout (git worktree add DIR COMMIT), as "
                        "'before', interleaved with the others; its ratios and the goal that no point "
                        "is slower than it are printed")
    p.add_argument("--no-ceiling", action="store_true", help="skip the ceiling server (no ratios)")
    p.add_argument("--no-rosgate", action="store_true", help="do not start rosgate")
    p.add_argument("--no-rust", action="store_true", help="--backend rclpy: skip the Rust server")
    p.add_argument("--no-netns", action="store_true",
                   help="--backend rclpy: stay on this machine's network (e.g. with --target on a ROS "
                        "machine) instead of a loopback-only namespace")
    p.add_argument("--ros-python", help="--backend rclpy: the Python with rclpy that runs rosgate and "
                                        "the ROS nodes (default .venv-ros/bin/python)")
    p.add_argument("--rosgate-arg", action="append", default=None,
                   help="argument for the rosgate command line, repeatable, e.g. --rosgate-arg=--talker "
                        "(default: --backend sim, --robot none and a scratch --programs-dir where offered)")
    p.add_argument("--quick", action="store_true", help="tiny durations, one repeat (a smoke run)")
    p.add_argument("--repeats", type=int, help="repeats per point (default 3)")
    p.add_argument("--duration", type=float, help="seconds per measured point (default 1.5)")
    p.add_argument("--slow-seconds", type=float, help="slow-consumer duration (default 60)")
    p.add_argument("--sizes", help="throughput payload sizes in bytes, comma-separated "
                                   "(default 64,1024,65536,1048576)")
    p.add_argument("--windows", help="throughput messages in flight, comma-separated (default 1,32)")
    p.add_argument("--fanout-rate", type=float, help="fan-out publish rate in Hz (default 10)")
    p.add_argument("--fanout-procs", type=int, help="subscriber worker processes (default 2)")
    p.add_argument("--no-malloc-tune", action="store_true",
                   help="leave glibc malloc thresholds alone in the clients and the ceiling")
    p.add_argument("--scenarios", help=f"comma-separated subset of {','.join(SCENARIOS)} "
                                       f"(--backend rclpy: of {','.join(ROS_SCENARIOS)})")
    p.add_argument("--out", help="write the figures as JSON to this file")
    p.add_argument("--py-spy", metavar="FILE",
                   help="sample the server under test with py-spy for the whole run: collapsed "
                        "stacks (and a summary printed) or, for FILE.svg, a flame graph")
    return p.parse_args(argv)


def make_config(args: argparse.Namespace) -> Config:
    ros = args.backend == "rclpy"
    cfg = rclpy_config(args.quick) if ros else quick_config() if args.quick else Config()
    if args.repeats:
        cfg.repeats = args.repeats
    if args.duration:
        cfg.point_s = args.duration
        cfg.fanout_s = max(args.duration, 0.5)
        cfg.rate_s = max(args.duration, 0.5)
    if args.sizes:
        cfg.sizes = [int(v) for v in args.sizes.split(",") if v.strip()]
    if args.windows:
        cfg.windows = [int(v) for v in args.windows.split(",") if v.strip()]
    if args.slow_seconds:
        cfg.slow_s = args.slow_seconds
    if args.fanout_rate:
        cfg.fanout_rate = args.fanout_rate
    if args.fanout_procs:
        cfg.fanout_procs = args.fanout_procs
    cfg.malloc_tune = not args.no_malloc_tune
    if args.scenarios:
        wanted = [s.strip() for s in args.scenarios.split(",") if s.strip()]
        unknown = set(wanted) - set(ROS_SCENARIOS if ros else SCENARIOS)
        if unknown:
            raise SystemExit(f"unknown scenario(s): {', '.join(sorted(unknown))}")
        cfg.scenarios = wanted
    return cfg


def loadavg() -> float:
    """The machine's 1-minute load average (/proc/loadavg): printed beside every figure."""
    try:
        with open("/proc/loadavg") as f:
            return float(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return float("nan")


def log(text: str, err: bool = False) -> None:
    print(text, file=sys.stderr if err else sys.stdout, flush=True)


def start_targets(args: argparse.Namespace) -> list[Target]:
    targets = []
    try:
        if not args.no_ceiling:
            targets.append(start_ceiling(malloc_tune=not args.no_malloc_tune))
        for i, url in enumerate(args.target):
            name = args.target_name[i] if i < len(args.target_name) else f"target{i + 1 if i else ''}"
            pid = args.server_pid[i] if i < len(args.server_pid) else None
            targets.append(Target(name=name, url=url, pid=pid))
        if (args.with_rosgate or not args.target) and not args.no_rosgate:
            if not rosgate_available():
                raise SystemExit("rosgate is not there yet (no gateway/__main__.py): "
                                 "use --no-rosgate or --target")
            targets.insert(1 if not args.no_ceiling else 0, start_rosgate(args.rosgate_arg))
            if args.baseline:
                targets.insert(2 if not args.no_ceiling else 1,
                               start_rosgate(args.rosgate_arg, checkout=args.baseline, name=BASELINE))
    except BaseException:
        for target in targets:
            target.stop()
        raise
    if not targets:
        raise SystemExit("nothing to measure: no ceiling, no rosgate, no --target")
    return targets


def start_ros_targets(args: argparse.Namespace) -> list[Target]:
    """rosgate on rclpy, the Rust server and the rclpy ceiling, in that order, then --target(s)."""
    targets = []
    try:
        if not args.no_rosgate:
            targets.append(rosgraph.start_rosgate_rclpy(args.rosgate_arg))
            if args.baseline:
                targets.append(rosgraph.start_rosgate_rclpy(args.rosgate_arg, checkout=args.baseline,
                                                            name=BASELINE))
        if not args.no_rust:
            why = rosgraph.rust_unavailable()
            if why:
                log(f"rust: column skipped: {why}")
            else:
                targets.append(rosgraph.start_rust())
        if not args.no_ceiling:
            targets.append(rosgraph.start_rclpy_ceiling())
        for i, url in enumerate(args.target):
            name = args.target_name[i] if i < len(args.target_name) else f"target{i + 1 if i else ''}"
            pid = args.server_pid[i] if i < len(args.server_pid) else None
            targets.append(Target(name=name, url=url, pid=pid))
    except BaseException:
        for target in targets:
            target.stop()
        raise
    if not targets:
        raise SystemExit("nothing to measure")
    return targets


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    ros = args.backend == "rclpy"
    if ros:
        if args.ros_python:
            os.environ[rosgraph.ROS_PYTHON_ENV] = args.ros_python
        rosgraph.check_ros_env()
        if not args.no_netns and not rosgraph.isolated():
            rosgraph.reexec_isolated(sys.argv[1:] if argv is None else argv)
    cfg = make_config(args)
    load_at_start = loadavg()
    if cfg.malloc_tune:
        tune_malloc()
    started = time.monotonic()
    graph = rosgraph.RosGraph() if ros else None
    ros_versions = rosgraph.versions() if ros else {}
    if ros_versions:
        log("ROS: " + ", ".join(f"{k} {v}" for k, v in ros_versions.items()))
    try:
        targets = start_ros_targets(args) if ros else start_targets(args)
    except BaseException:
        if graph is not None:
            graph.stop()
        raise
    spy = None
    try:
        for t in targets:
            log(f"{t.name}: {t.url} pid {t.pid if t.pid else 'unknown (no CPU/RSS figures)'}"
                + (f" ({' '.join(t.argv)})" if t.argv else ""))
        idle = {t.name: asyncio.run(idle_cpu(t, 0.3 if args.quick else 1.0)) for t in targets}
        if args.py_spy:
            profiled = next((t for t in targets if t.kind != "ceiling" and t.pid), None)
            if profiled is None:
                raise SystemExit("--py-spy needs rosgate or --target with --server-pid")
            spy = PySpy(profiled.pid, args.py_spy)
        results = asyncio.run(run_all(cfg, targets, log, ros))
    finally:
        if spy is not None:
            log(spy.stop())
        for t in targets:
            t.stop()
        if graph is not None:
            graph.stop()
    primary = next((t.name for t in targets if t.kind not in ("ceiling", "rclpy")), None)
    if ros:
        goal_rows = report.goals_rclpy(results, primary) if primary else []
    else:
        goal_rows = report.goals(results, primary) if primary and not args.no_ceiling else []
    if goal_rows:
        log(report.goals_table(goal_rows, primary))
    total = time.monotonic() - started
    log(f"\nidle server CPU %: {', '.join(f'{k} {report.fmt(v)}' for k, v in idle.items())}; "
        f"total {total:.0f} s; load average {load_at_start:.2f} at the start, {loadavg():.2f} at the end")
    if args.out:
        doc = {
            "meta": {
                "python": platform.python_version(), "cpus": _cpus(), "cpu_model": _cpu_model(),
                "client": f"websockets {websockets.__version__}", "tornado": tornado.version,
                "config": asdict(cfg), "total_s": total, "idle_server_cpu_pct": idle,
                "backend": args.backend, "ros": ros_versions,
                "targets": [{"name": t.name, "url": t.url, "pid": t.pid, "kind": t.kind, "argv": t.argv}
                            for t in targets],
            },
            "results": results,
            "goals": goal_rows,
        }
        with open(args.out, "w") as f:
            json.dump(doc, f, indent=1)
        log(f"wrote {args.out}")
    return 0


def _cpus() -> int:
    import os
    return len(os.sched_getaffinity(0))


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()
