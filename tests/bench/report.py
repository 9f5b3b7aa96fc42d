"""Summaries (median and spread of repeats), ratios to the ceiling, tables, goals."""

from __future__ import annotations

import json
import statistics
from pathlib import Path

# The metrics most tables end with: the CPU of the server, the clients and the rest of the machine.
CPU = [("server_cpu_pct", "srv CPU%"), ("client_cpu_pct", "cli CPU%"), ("other_cpu_pct", "other%"),
       ("load1", "load")]   # load: the 1-minute load average as each run ended
LATENCY = [("lat_p50_ms", "p50 ms"), ("lat_p95_ms", "p95 ms"), ("lat_p99_ms", "p99 ms")]
# Per scenario: the metrics shown in its table, with their headings.
COLUMNS = {
    "throughput": [
        ("msg_per_s", "msg/s"), *LATENCY, ("delivered_pct", "deliv%"), ("server_us_per_msg", "srv us/msg"), *CPU,
    ],
    "fanout": [
        ("delivered_pct", "deliv%"), ("server_cpu_pct", "srv CPU%"),
        ("server_cpu_s_per_1000", "srv CPU s/1000"), *LATENCY[:2], *CPU[1:],
    ],
    "encodings": [
        ("hz", "max Hz"), ("wire_kib", "wire KiB"), ("publish_kib", "in KiB"),
        ("server_ms_per_msg", "srv ms/msg"), ("delivered_pct", "deliv%"), *CPU,
    ],
    "encodings_rate": [
        ("published_hz", "pub Hz"), ("delivered_pct", "deliv%"),
        ("server_ms_per_msg", "srv ms/msg"), ("server_cores", "srv cores"), *CPU[1:],
    ],
    "images": [
        ("sub_hz", "Hz each (min)"), ("published_hz", "pub Hz"), ("delivered_pct", "deliv%"),
        ("server_ms_per_msg", "srv ms/msg"), *CPU,
    ],
    "services": [
        ("calls_per_s", "calls/s"), *LATENCY, ("failed", "failed"), ("server_us_per_call", "srv us/call"), *CPU,
    ],
    "slow_consumer": [
        ("published_hz", "pub Hz"), ("healthy_hz_before", "others Hz before"),
        ("healthy_hz_stalled", "others Hz stalled"), ("healthy_loss_pct", "others loss%"),
        ("rss_at_stall_mb", "RSS MB at stall"), ("rss_max_mb", "RSS MB max"),
        ("rss_growth_mb", "RSS growth MB"), *CPU,
    ],
}

NO_RATIO = {"other_cpu_pct", "failed", "load1"}  # load from elsewhere, and counts: no ratio

TITLES = {
    "throughput": "1. Throughput and one-way latency: std_msgs/String, 1 publisher + 1 subscriber, W in flight",
    "fanout": "2. Fan-out: 1 publisher, N subscribers (in worker processes), fixed rate",
    "encodings": "3a. Encodings: max sustained rate to 1 subscriber (publisher sends JSON)",
    "encodings_rate": "3b. Encodings at a fixed rate (0 subscribers = ingest of the JSON publish only)",
    "services": "4. Services: /add_two_ints (example_interfaces/srv/AddTwoInts), C calls in flight",
    "slow_consumer": "5. Slow consumer: 640x480 rgb8 at 30 Hz to 3 cbor subscribers, one stops reading",
}

# --backend rclpy: the ROS end is plain rclpy nodes; the rclpy ceiling runs the same traffic
# between rclpy nodes in one process (its CPU is that process's)
ROS_TITLES = dict(
    TITLES,
    fanout="2. Fan-out: 1 publisher, N subscribers (websocket clients in worker processes; "
           "rclpy: N subscriptions in one node), fixed rate",
    images="3. Images: a 30 Hz 640x480 rgb8 camera node (rclpy) to 3 clients of one encoding "
           "(rclpy: 3 subscriber nodes)",
    services="4. Services: /add_two_ints served by an rclpy node (SingleThreadedExecutor) as "
             "test_msgs/srv/BasicTypes (example_interfaces is not on PyPI), C calls in flight",
    slow_consumer="5. Slow consumer: the camera node's images to 3 cbor subscribers, one stops reading",
)


def save(path: str | None, doc) -> None:
    """A bench's figures as JSON at ``--out`` (nothing without it)."""
    if path:
        Path(path).write_text(json.dumps(doc, indent=1))


def title(scenario: str, ros: bool = False) -> str:
    return (ROS_TITLES if ros else TITLES)[scenario]


def summarize(runs: list[dict]) -> dict:
    out = {}
    keys = {k for run in runs for k, v in run.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    for key in sorted(keys):
        values = [run[key] for run in runs if isinstance(run.get(key), (int, float))]
        if not values:
            continue
        median = statistics.median(values)
        spread = (max(values) - min(values)) / 2 / abs(median) * 100 if median else 0.0
        out[key] = {"median": median, "min": min(values), "max": max(values),
                    "spread_pct": spread, "n": len(values)}
    return out


def finish_point(entry: dict, bases: tuple[str, ...] = ("ceiling",), baseline: str | None = None) -> None:
    """Add summary and ratios to one point's entry in place.

    `ratios[base][name]` is each other server's figure over the base's (the ceiling, or in
    `--backend rclpy` the Rust server and the rclpy ceiling); `ratio` is the first base's. With a
    `baseline` (another checkout's rosgate) its figures get ratios to the bases too, and the
    others' to it."""
    entry["summary"] = {name: summarize(runs) for name, runs in entry["runs"].items() if runs}
    entry["ratios"] = {}
    for base in (*bases, baseline) if baseline else bases:
        reference = entry["summary"].get(base)
        if not reference:
            continue
        entry["ratios"][base] = {}
        for name, summary in entry["summary"].items():
            if name in bases or name == base:
                continue
            ratios = {}
            for key, stats in summary.items():
                if key in NO_RATIO:
                    continue
                value = reference.get(key, {}).get("median")
                if value:
                    ratios[key] = stats["median"] / value
            entry["ratios"][base][name] = ratios
    entry["ratio"] = entry["ratios"].get(bases[0], {})


def fmt(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    magnitude = abs(value)
    if magnitude >= 1000:
        return f"{value:,.0f}"
    if magnitude >= 100:
        return f"{value:.0f}"
    if magnitude >= 10:
        return f"{value:.1f}"
    if magnitude >= 1:
        return f"{value:.2f}"
    if magnitude == 0:
        return "0"
    return f"{value:.3f}"


def table(scenario: str, entries: list[dict], targets: list[str]) -> str:
    columns = COLUMNS[scenario]
    header = ["point", "server"] + [title for _key, title in columns]
    rows = [header]
    for entry in entries:
        label = entry["label"]
        for name in targets:
            if name in entry.get("errors", {}):
                rows.append([label, name, "error: " + entry["errors"][name][:90]])
                label = ""
                continue
            summary = entry.get("summary", {}).get(name)
            if not summary:
                continue
            cells = []
            for i, (key, _title) in enumerate(columns):
                stats = summary.get(key)
                if stats is None:
                    cells.append("-")
                elif i == 0 and stats["n"] > 1:
                    cells.append(f"{fmt(stats['median'])} ±{stats['spread_pct']:.0f}%")
                else:
                    cells.append(fmt(stats["median"]))
            rows.append([label, name] + cells)
            label = ""
        for base, per_name in entry.get("ratios", {}).items():
            for name, ratios in per_name.items():
                if ratios:
                    rows.append(["", f"{name}/{'ceil' if base == 'ceiling' else base}"] + [
                        "-" if key not in ratios else f"{ratios[key]:.2f}x" for key, _t in columns])
    return _render(rows)


def _render(rows: list[list[str]]) -> str:
    width = max(len(r) for r in rows)
    widths = [max(len(r[i]) for r in rows if i < len(r)) for i in range(width)]
    lines = []
    for n, row in enumerate(rows):
        if len(row) == 3 and row[2].startswith("error:"):
            lines.append(f"{row[0]:<{widths[0]}}  {row[1]:<{widths[1]}}  {row[2]}")
        else:
            lines.append("  ".join(
                cell.ljust(widths[i]) if i < 2 else cell.rjust(widths[i]) for i, cell in enumerate(row)))
        if n == 0:
            lines.append("-" * len(lines[0]))
    return "\n".join(lines)


def _median(results: dict, scenario: str, match: dict, target: str, key: str):
    for entry in results.get(scenario, []):
        if all(entry["point"].get(k) == v for k, v in match.items()):
            return entry.get("summary", {}).get(target, {}).get(key, {}).get("median")
    return None


def _ratio(results: dict, scenario: str, match: dict, target: str, key: str):
    for entry in results.get(scenario, []):
        if all(entry["point"].get(k) == v for k, v in match.items()):
            return entry.get("ratio", {}).get(target, {}).get(key)
    return None


def goals(results: dict, target: str) -> list[dict]:
    """The issue's goals, each with the measured figure and whether it is met.

    Goals of scenarios that did not run are left out."""
    out = []

    def add(scenario: str, goal: str, value, ok: bool) -> None:
        if scenario in results:
            out.append({"goal": goal, "value": value, "met": None if value is None else ok})

    for size in (64, 1024):
        for w in (1, 32):
            r = _ratio(results, "throughput", {"size": size, "window": w}, target, "msg_per_s")
            add("throughput", f">= 60% of ceiling msg/s at {size} B, W={w}", r, r is not None and r >= 0.6)
    for n in (1, 100):
        v = _median(results, "fanout", {"subscribers": n}, target, "server_cpu_pct")
        add("fanout", f"fan-out {n} subscriber(s) at the fan-out rate x 1 KiB < 10% of a core (srv CPU%)",
            v, v is not None and v < 10)
    image30 = {"subscribers": 3, "compression": "cbor"}
    v = _median(results, "encodings_rate", image30, target, "server_cores")
    d = _median(results, "encodings_rate", image30, target, "delivered_pct")
    add("encodings_rate", "640x480 rgb8 at 30 Hz to 3 cbor clients < 1 core (srv cores)", v,
        v is not None and v < 1 and (d or 0) >= 99)
    v = _median(results, "throughput", {"size": 64, "window": 1}, target, "lat_p95_ms")
    add("throughput", "p95 one-way latency < 0.5 ms at 64 B, W=1 (ms)", v, v is not None and v < 0.5)
    v = _median(results, "slow_consumer", {}, target, "healthy_loss_pct")
    add("slow_consumer", "a stalled client costs the others < 5% (others' loss %)", v,
        v is not None and v < 5)
    v = _median(results, "slow_consumer", {}, target, "rss_growth_mb")
    add("slow_consumer", "a stalled client costs the server < 50 MB (RSS growth MB)", v,
        v is not None and v < 50)
    for size in (64, 1024):   # issue 51: past the bare tornado relay, on a faster websocket path
        r = _ratio(results, "throughput", {"size": size, "window": 32}, target, "msg_per_s")
        add("throughput", f">= the bare tornado relay's (ceiling's) msg/s at {size} B, W=32", r,
            r is not None and r >= 1)
    return out + not_slower(results, target)


def goals_rclpy(results: dict, target: str) -> list[dict]:
    """The goals of issue 16 (rosgate on rclpy with Fast DDS), against the same run's figures."""
    out = []

    def add(scenario: str, goal: str, value, ok) -> None:
        if scenario in results:
            out.append({"goal": goal, "value": value, "met": None if value is None else bool(ok(value))})

    def vs(scenario: str, match: dict, key: str, base: str):
        for entry in results.get(scenario, []):
            if all(entry["point"].get(k) == v for k, v in match.items()):
                return entry.get("ratios", {}).get(base, {}).get(target, {}).get(key)
        return None

    for size in (64, 1024):   # issue 51
        r = vs("throughput", {"size": size, "window": 32}, "msg_per_s", "rust")
        add("throughput", f">= 1.2x the Rust server's msg/s at {size} B, W=32", r, lambda v: v >= 1.2)
    r = vs("throughput", {"size": 65536, "window": 32}, "msg_per_s", "rust")
    add("throughput", ">= the Rust server's msg/s at 64 KiB, W=32", r, lambda v: v >= 1)
    for size in (64, 1024):   # issue 51
        r = vs("throughput", {"size": size, "window": 1}, "lat_p50_ms", "rust")
        add("throughput", f"p50 one-way latency <= the Rust server's at {size} B, W=1 (ratio)", r, lambda v: v <= 1)
    v = _median(results, "throughput", {"size": 64, "window": 1}, target, "lat_p50_ms")
    add("throughput", "p50 one-way latency <= 0.5 ms at 64 B, W=1 (ms)", v, lambda v: v <= 0.5)
    r = vs("services", {"concurrency": 32}, "calls_per_s", "rust")
    add("services", ">= 2x the Rust server's calls/s at C=32", r, lambda v: v >= 2)
    r = vs("services", {"concurrency": 32}, "calls_per_s", "rclpy")
    add("services", ">= 60% of the rclpy ceiling's calls/s at C=32", r, lambda v: v >= 0.6)
    v = _median(results, "services", {"concurrency": 1}, target, "lat_p50_ms")
    add("services", "call p50 < 1 ms at C=1 (ms)", v, lambda v: v < 1)
    v = _median(results, "fanout", {"subscribers": 100}, target, "server_cpu_pct")
    d = _median(results, "fanout", {"subscribers": 100}, target, "delivered_pct")
    add("fanout", "100 subscribers at the fan-out rate x 1 KiB < 5% of a core, nothing lost (srv CPU%)",
        v, lambda v: v < 5 and (d or 0) >= 100)
    for enc, limit in (("none", 20), ("cbor", 10)):
        v = _median(results, "images", {"compression": enc}, target, "server_cpu_pct")
        hz = _median(results, "images", {"compression": enc}, target, "sub_hz")
        label = "JSON" if enc == "none" else "CBOR"
        add("images", f"640x480 rgb8 30 Hz to 3 {label} clients: 30 Hz each, < {limit}% of a core "
            "(srv CPU%)", v, lambda v, hz=hz, limit=limit: v < limit and (hz or 0) >= 29)
    v = _median(results, "slow_consumer", {}, target, "healthy_loss_pct")
    add("slow_consumer", "a stalled client costs the others nothing (< 5% loss; others' loss %)", v,
        lambda v: v < 5)
    return out + not_slower(results, target)


# per scenario, the figure that says faster (higher is better) for the baseline's goal
FASTER = {"throughput": "msg_per_s", "services": "calls_per_s", "images": "sub_hz", "encodings": "hz"}
NOT_SLOWER = 0.9   # below this share of the baseline's figure a point counts as slower (shared machines)


def not_slower(results: dict, target: str, baseline: str = "before") -> list[dict]:
    """Issue 51's "no probe slower than today": the lowest ratio target/baseline over the points
    with a FASTER figure, when the run had a baseline (--baseline)."""
    worst = None
    for scenario, key in FASTER.items():
        for entry in results.get(scenario, []):
            r = entry.get("ratios", {}).get(baseline, {}).get(target, {}).get(key)
            if r is not None and (worst is None or r < worst[0]):
                worst = (r, f"{scenario} {entry['label']}")
    if worst is None:
        return []
    return [{"goal": f"no point slower than --baseline (lowest ratio, at {worst[1]}; >= {NOT_SLOWER})",
             "value": worst[0], "met": worst[0] >= NOT_SLOWER}]


def goals_table(rows: list[dict], target: str) -> str:
    lines = [f"Goals ({target}; reported, not asserted)"]
    for row in rows:
        mark = {True: "met", False: "NOT met", None: "no figure"}[row["met"]]
        lines.append(f"  {mark:<9}  {fmt(row['value']):>8}  {row['goal']}")
    return "\n".join(lines)
