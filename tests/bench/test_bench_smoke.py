"""The benchmark harness in its --quick mode: every scenario yields figures.

Runs against the ceiling server, and against rosgate when the gateway is there; with
`--backend rclpy` against rosgate on rclpy and the rclpy ceiling when `.venv-ros` and
`unshare` are there.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import cbor2
import orjson
import pytest

from tests.bench.client import StringFrames, is_publish, read_stamp
from tests.bench.report import finish_point, goals, goals_rclpy
from tests.bench.rosgraph import ROS_VENV
from tests.bench.rosplan import image_seq
from tests.bench.servers import REPO, rosgate_available, start_ceiling

# scenario -> metrics that must be positive numbers for every server
REQUIRED = {
    "throughput": ["msg_per_s", "lat_p50_ms", "lat_p95_ms", "delivered_pct"],
    "fanout": ["delivered_pct", "lat_p95_ms"],
    "encodings": ["hz", "wire_kib", "delivered_pct"],
    "encodings_rate": ["published_hz"],
    "services": ["calls_per_s", "lat_p95_ms"],
    "slow_consumer": ["published_hz", "healthy_hz_before", "healthy_hz_stalled"],
}
# metrics that need the server's pid: numbers, possibly zero
MEASURED = {
    "throughput": ["server_cpu_pct"],
    "fanout": ["server_cpu_s_per_1000"],
    "encodings": ["server_ms_per_msg"],
    "encodings_rate": ["server_ms_per_msg"],
    "services": ["server_us_per_call"],
    "slow_consumer": ["rss_at_stall_mb", "rss_growth_mb"],
}


def run_quick(tmp_path, *args: str, timeout: float = 90) -> dict:
    out = tmp_path / "bench.json"
    proc = subprocess.run(
        [sys.executable, "-m", "tests.bench", "--quick", "--out", str(out), *args],
        cwd=REPO, capture_output=True, text=True, timeout=timeout,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "1. Throughput" in proc.stdout and "5. Slow consumer" in proc.stdout
    return json.loads(out.read_text())


def check_figures(doc: dict, servers: list[str]) -> None:
    assert [t["name"] for t in doc["meta"]["targets"]] == servers
    results = doc["results"]
    assert set(results) == set(REQUIRED)
    for scenario, entries in results.items():
        assert entries, scenario
        for entry in entries:
            assert entry["errors"] == {}, (scenario, entry["label"], entry["errors"])
            for server in servers:
                summary = entry["summary"][server]
                for key in REQUIRED[scenario]:
                    assert summary[key]["median"] > 0, (scenario, entry["label"], server, key)
                for key in MEASURED[scenario]:
                    assert summary[key]["median"] >= 0, (scenario, entry["label"], server, key)


def test_quick_bench_yields_every_figure(tmp_path):
    """Against the ceiling and rosgate (the ceiling alone until the gateway exists)."""
    with_rosgate = rosgate_available()
    doc = run_quick(tmp_path, *([] if with_rosgate else ["--no-rosgate"]))
    check_figures(doc, ["ceiling", "rosgate"] if with_rosgate else ["ceiling"])
    if not with_rosgate:
        assert doc["goals"] == []
        return
    for entry in doc["results"]["throughput"]:
        assert entry["ratio"]["rosgate"]["msg_per_s"] > 0
    # quick mode stops at 10 subscribers, so the 100-subscriber goal has no figure
    assert all(goal["value"] is not None for goal in doc["goals"]
               if "100 subscriber" not in goal["goal"])


def test_stamped_frames_read_back():
    frames = StringFrames("/bench/t", 64)
    frame = frames.frame(42)
    assert len(frame) == len(b'{"op":"publish","topic":"/bench/t","msg":{"data":""}}') + 64
    seq, stamp = read_stamp(frame)
    assert seq == 42 and stamp > 0
    # the reference server's json.dumps puts a space after colons
    spaced = frame.replace(b'"data":"', b'"data": "')
    assert read_stamp(spaced) == (42, stamp)
    assert is_publish(frame) and is_publish(b"\xa3cbor")
    assert not is_publish(b'{"op":"status","level":"error","msg":"no"}')


def test_ratio_and_goal_from_runs():
    entry = {"point": {"size": 64, "window": 1}, "runs": {
        "ceiling": [{"msg_per_s": 100.0, "lat_p95_ms": 0.2}, {"msg_per_s": 120.0, "lat_p95_ms": 0.3}],
        "rosgate": [{"msg_per_s": 50.0, "lat_p95_ms": 0.4}, {"msg_per_s": 70.0, "lat_p95_ms": 0.8},
                    {"msg_per_s": 60.0, "lat_p95_ms": 0.6}],
    }}
    finish_point(entry)
    assert entry["summary"]["rosgate"]["msg_per_s"]["median"] == 60.0
    assert entry["summary"]["ceiling"]["msg_per_s"]["median"] == 110.0
    assert entry["ratio"]["rosgate"]["msg_per_s"] == pytest.approx(60 / 110)
    rows = {g["goal"]: g for g in goals({"throughput": [entry]}, "rosgate")}
    assert rows[">= 60% of ceiling msg/s at 64 B, W=1"]["met"] is False
    assert rows["p95 one-way latency < 0.5 ms at 64 B, W=1 (ms)"]["met"] is False


def test_target_and_server_pid_measure_a_running_server(tmp_path):
    """--target with --server-pid: the harness measures a server it did not start."""
    server = start_ceiling()
    try:
        out = tmp_path / "target.json"
        proc = subprocess.run(
            [sys.executable, "-m", "tests.bench", "--quick", "--no-ceiling", "--scenarios", "throughput",
             "--target", server.url, "--server-pid", str(server.pid), "--target-name", "other",
             "--out", str(out)],
            cwd=REPO, capture_output=True, text=True, timeout=60,
        )
        assert proc.returncode == 0, proc.stderr[-3000:]
        doc = json.loads(out.read_text())
    finally:
        server.stop()
    assert [t["name"] for t in doc["meta"]["targets"]] == ["other"]
    assert doc["meta"]["targets"][0]["pid"] == server.pid
    for entry in doc["results"]["throughput"]:
        summary = entry["summary"]["other"]
        assert summary["msg_per_s"]["median"] > 0
        assert summary["server_cpu_pct"]["median"] > 0


# --backend rclpy: scenario -> metrics that must be positive for rosgate and the rclpy ceiling
ROS_REQUIRED = {
    "throughput": ["msg_per_s", "lat_p50_ms", "delivered_pct", "server_cpu_pct"],
    "fanout": ["delivered_pct", "server_cpu_pct"],
    "images": ["sub_hz", "published_hz", "delivered_pct", "server_cpu_pct"],
    "services": ["calls_per_s", "lat_p50_ms", "server_cpu_pct"],
    "slow_consumer": ["published_hz", "healthy_hz_before"],
}


@pytest.mark.skipif(not (ROS_VENV / "bin" / "python").exists() or shutil.which("unshare") is None,
                    reason="needs .venv-ros (rclpy) and unshare")
@pytest.mark.timeout(420)
def test_quick_rclpy_bench_yields_every_figure(tmp_path):
    """rosgate on rclpy against the rclpy ceiling, in the namespace the harness makes for itself."""
    doc = run_quick(tmp_path, "--backend", "rclpy", "--no-rust", timeout=400)
    assert [t["name"] for t in doc["meta"]["targets"]] == ["rosgate", "rclpy"]
    results = doc["results"]
    assert set(results) == set(ROS_REQUIRED)
    for scenario, entries in results.items():
        for entry in entries:
            assert entry["errors"] == {}, (scenario, entry["label"], entry["errors"])
            servers = ["rosgate"] if scenario == "slow_consumer" else ["rosgate", "rclpy"]
            assert sorted(entry["summary"]) == sorted(servers), (scenario, entry["label"])
            for server in servers:
                for key in ROS_REQUIRED[scenario]:
                    assert entry["summary"][server][key]["median"] > 0, (scenario, entry["label"], server, key)
            if scenario != "slow_consumer":
                assert entry["ratios"]["rclpy"]["rosgate"], (scenario, entry["label"])
    rows = {g["goal"]: g for g in doc["goals"]}
    assert rows["call p50 < 1 ms at C=1 (ms)"]["value"] > 0
    assert rows[">= 60% of the rclpy ceiling's calls/s at C=32"]["value"] > 0


@pytest.mark.skipif(not (ROS_VENV / "bin" / "python").exists() or shutil.which("unshare") is None,
                    reason="needs .venv-ros (make .venv-ros/.installed) and unshare")
def test_steps_of_a_publish_each_get_a_figure():
    """python -m tests.bench.steps: every step of the rclpy publish path, timed at each size."""
    proc = subprocess.run([sys.executable, "-m", "tests.bench.steps", "--sizes", "64,65536", "--windows", "2"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = [line.rsplit(None, 2) for line in proc.stdout.splitlines()[1:]]
    names = [row[0].strip() for row in rows]
    assert "JSON -> dict (decode_text)" in names and "DDS publish + own reader take" in names, proc.stdout
    assert names[-1] == "sum" and len(names) == 11, proc.stdout
    for name, small, large in rows:
        assert float(small) > 0 and float(large) > 0, (name, proc.stdout)


def test_image_sequence_read_from_json_and_cbor_frames():
    for seq in (0, 23, 24, 300, 70_000, 2**33):
        msg = {"header": {"stamp": {"sec": seq, "nanosec": 9}, "frame_id": "camera"}, "data": b"x" * 100}
        assert image_seq(cbor2.dumps({"op": "publish", "topic": "/c", "msg": msg})) == seq
        msg["data"] = "eHh4"
        assert image_seq(orjson.dumps({"op": "publish", "topic": "/c", "msg": msg})) == seq
        spaced = b'{"op": "publish", "msg": {"header": {"stamp": {"nanosec": 1, "sec": %d}}}}' % seq
        assert image_seq(spaced) == seq
    assert image_seq(b'{"op":"publish","msg":{"data":"x"}}') is None


def test_ratios_to_each_base_and_rclpy_goals():
    entry = {"point": {"size": 64, "window": 32}, "runs": {
        "rosgate": [{"msg_per_s": 9000.0}], "rust": [{"msg_per_s": 10000.0}], "rclpy": [{"msg_per_s": 4500.0}],
    }}
    finish_point(entry, ("rust", "rclpy"))
    assert entry["ratios"]["rust"]["rosgate"]["msg_per_s"] == pytest.approx(0.9)
    assert entry["ratios"]["rclpy"]["rosgate"]["msg_per_s"] == pytest.approx(2.0)
    assert "rust" not in entry["ratios"]["rclpy"]  # bases get no ratio rows of their own
    assert entry["ratio"] == entry["ratios"]["rust"]
    rows = {g["goal"]: g for g in goals_rclpy({"throughput": [entry]}, "rosgate")}
    assert rows[">= 1.2x the Rust server's msg/s at 64 B, W=32"]["met"] is False   # 0.9x
    assert rows[">= 1.2x the Rust server's msg/s at 1024 B, W=32"]["met"] is None
    assert not any("--baseline" in goal for goal in rows)   # no baseline in this run


def test_a_baseline_gets_ratios_and_the_not_slower_goal():
    """--baseline: the other checkout's rosgate ('before') gets ratios to the Rust server, rosgate
    gets ratios to it, and the lowest of those is the goal that no point is slower."""
    fast = {"point": {"size": 64, "window": 32}, "label": "64B W=32", "runs": {
        "rosgate": [{"msg_per_s": 12000.0}], "before": [{"msg_per_s": 8000.0}], "rust": [{"msg_per_s": 10000.0}]}}
    slow = {"point": {"size": 64, "window": 1}, "label": "64B W=1", "runs": {
        "rosgate": [{"msg_per_s": 800.0, "lat_p50_ms": 0.2}], "before": [{"msg_per_s": 1000.0}],
        "rust": [{"msg_per_s": 900.0, "lat_p50_ms": 0.25}]}}
    for entry in (fast, slow):
        finish_point(entry, ("rust",), "before")
    assert fast["ratios"]["rust"]["before"]["msg_per_s"] == pytest.approx(0.8)
    assert fast["ratios"]["before"]["rosgate"]["msg_per_s"] == pytest.approx(1.5)
    assert "rust" not in fast["ratios"]["before"]
    rows = {g["goal"]: g for g in goals_rclpy({"throughput": [fast, slow]}, "rosgate")}
    assert rows[">= 1.2x the Rust server's msg/s at 64 B, W=32"]["met"] is True
    assert rows["p50 one-way latency <= the Rust server's at 64 B, W=1 (ratio)"]["value"] == pytest.approx(0.8)
    slower = next(g for g in rows.values() if "--baseline" in g["goal"])
    assert slower["value"] == pytest.approx(0.8) and slower["met"] is False and "64B W=1" in slower["goal"]


def test_lesson_run_yields_its_figures(tmp_path):
    """`python -m tests.bench lesson` for a few seconds on two stations: every figure is there (the
    bar is for the full run and is not judged here)."""
    if not rosgate_available():
        pytest.skip("no gateway")
    out = tmp_path / "lesson.json"
    proc = subprocess.run(
        [sys.executable, "-m", "tests.bench", "lesson", "--stations", "2", "--minutes", "0.05",
         "--warmup", "1", "--out", str(out)],
        cwd=REPO, capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode in (0, 1), proc.stderr[-3000:]
    assert "the bar:" in proc.stdout
    doc = json.loads(out.read_text())
    assert doc["namespaces"] == ["/s01", "/s02"]
    (minute,) = doc["minutes"]
    assert minute["rss_mb"] > 0 and minute["cpu_pct"] > 0 and minute["pose_per_s"] > 0
    assert minute["rosapi_calls"] > 0 and minute["rosapi_p95_ms"] > 0
    late = doc["late_viewer"]
    assert late["topic"] == "/s01/world/markers" and late["bytes"] > 0
    assert {"bounds", "robots", "pen"} <= set(late["markers"])
    assert len(doc["bar"]) == 5



def test_camera_bench_yields_its_figures(tmp_path):
    """`python -m tests.bench camera` for a few seconds: every client's figures are there."""
    if not rosgate_available():
        pytest.skip("no gateway")
    out = tmp_path / "camera.json"
    proc = subprocess.run([sys.executable, "-m", "tests.bench", "camera", "--seconds", "1.5", "--out", str(out)],
                          cwd=REPO, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr[-3000:]
    doc = json.loads(out.read_text())
    for name in ("ws-default", "ws-teleop", "ws-image", "stream-slow", "stream-slow-full"):
        assert doc[name]["frames"] > 0 and doc[name]["age_p95"] is not None, (name, doc[name])
    assert doc["viewers-12"]["frames_per_viewer_per_s"] > 0 and doc["cpu_ratio_12_to_1"] is not None


def test_history_bench_gives_its_figures(tmp_path):
    """`python -m tests.bench history` in a short run: both halves give numbers (the bar is the
    full run's to judge, on a quiet machine)."""
    out = tmp_path / "history.json"
    res = subprocess.run([sys.executable, "-m", "tests.bench", "history", "--seconds", "3", "--series", "1",
                          "--out", str(out)], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert res.returncode in (0, 1), res.stderr[-2000:]
    figures = json.loads(out.read_text())
    assert figures["write"]["rows"] >= 2 * 150 and figures["write"]["cpu_pct_of_core"] > 0
    read = figures["read"]
    assert read["points"] == read["http_points"] == 86_400
    assert read["http_raw"]["p50_ms"] > 0 and read["http_step60"]["p50_ms"] > 0
    assert "history read: one field over a day" in res.stdout


def test_run_archive_bench_keeps_every_line_and_gives_its_cost(tmp_path):
    """`python -m tests.bench runs` in a short run: the output read back is what was printed, and
    past a small cap it is cut where the archive says."""
    out = tmp_path / "runs.json"
    res = subprocess.run([sys.executable, "-m", "tests.bench", "runs", "--seconds", "2", "--runs", "3",
                          "--out", str(out)], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    w = json.loads(out.read_text())
    assert w["lines_per_run"] >= 1000 and w["kept_lines_first_run"] == w["lines_per_run"] and not w["cut"]
    assert w["cpu_pct_of_core"] > 0 and w["db_bytes"] > 3 * 1000 * 30
    assert "run archive write: 3 runs printing at 1000 Hz" in res.stdout
    res = subprocess.run([sys.executable, "-m", "tests.bench", "runs", "--seconds", "1", "--runs", "2",
                          "--cap", "4096", "--out", str(out)], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    w = json.loads(out.read_text())
    assert w["cut"] and w["kept_lines_first_run"] < 4096 // 30 and "(cut at the cap)" in res.stdout


def test_foxglove_bench_yields_its_figures(tmp_path):
    """`python -m tests.bench foxglove` briefly: both paths deliver, every figure is there."""
    if not rosgate_available():
        pytest.skip("no gateway")
    out = tmp_path / "foxglove.json"
    proc = subprocess.run([sys.executable, "-m", "tests.bench", "foxglove", "--seconds", "0.5", "--repeats", "1",
                           "--out", str(out)], cwd=REPO, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr[-3000:]
    doc = json.loads(out.read_text())
    assert set(doc["rate"]) == {"rosbridge 64 B", "foxglove 64 B", "rosbridge 1024 B", "foxglove 1024 B"}
    for point in doc["rate"].values():
        assert point["msg_per_s"]["median"] > 0 and point["server_us_per_msg"]["median"] > 0
    assert set(doc["camera"]) == {"in only", "3 json", "3 cbor", "3 foxglove", "3 foxglove-apart"}
    for label, point in doc["camera"].items():
        assert point["published_hz"]["median"] > 0 and "other_cpu_pct" in point
        if label != "in only":
            assert point["slowest_hz"]["median"] > 0
    assert len(doc["loadavg_before"]) == 3
