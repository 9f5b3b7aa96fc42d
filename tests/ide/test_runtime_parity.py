"""The JavaScript runtime helpers (in Chromium) and the Python runtime copied into generated
programs give the same answers, so a program logs and decides the same in both languages."""

from __future__ import annotations

import math

import pytest


def js(page, expr: str, arg=None):
    return page.evaluate(f"async (arg) => {{ const u = await import('/runtime/util.js'); return {expr}; }}", arg)


VALUES = [1, -7, 2.5, 0.1 + 0.2, -0.001, 123456789.125, "text", "", True, False, None,
          [1, [2, "a"], []], {"a": 1, "b": [True, None], "c": {"d": "é"}}, [0.5, 3]]


def test_log_format(util_page, py_runtime):
    assert js(util_page, "arg.map(u.fmt)", VALUES) == [py_runtime.fmt(v) for v in VALUES]
    assert js(util_page, "[u.fmt(NaN), u.fmt(Infinity), u.fmt(-Infinity), u.fmt(4.0)]") == [
        py_runtime.fmt(math.nan), py_runtime.fmt(math.inf), py_runtime.fmt(-math.inf), py_runtime.fmt(4.0)]


def test_fields(util_page, py_runtime):
    msg = {"pose": {"pose": {"position": {"x": 1.5}}}, "ranges": [3, 4, 5]}
    for path in ("pose.pose.position.x", "ranges.1", "ranges", ""):
        assert js(util_page, f"u.field(arg, {path!r})", msg) == py_runtime.field(msg, path)
    with pytest.raises(Exception):
        py_runtime.field(msg, "pose.nothing")
    assert "nothing" in js(util_page, "(() => { try { u.field(arg, 'pose.nothing'); } catch (e) { return e.message; } })()", msg)


def test_yaw_and_ranges(util_page, py_runtime):
    for deg in (0, 45, 90, 179, -90, -135):
        th = math.radians(deg)
        q = {"x": 0, "y": 0, "z": math.sin(th / 2), "w": math.cos(th / 2)}
        assert js(util_page, "u.yaw(arg)", q) == pytest.approx(py_runtime.yaw(q), abs=1e-12)
        assert py_runtime.yaw(q) == pytest.approx(th, abs=1e-9)
    n = 360
    scan = {"angle_min": -math.pi, "angle_increment": 2 * math.pi / n, "range_min": 0.1, "range_max": 10,
            "ranges": [2.0 + (i % 7) * 0.1 for i in range(n)]}
    scan["ranges"][180] = 0.5        # straight ahead
    scan["ranges"][270] = 0.05       # left, below range_min: ignored
    scan["ranges"][275] = None       # NaN arrives as null
    for deg, window in ((0, 30), (90, 30), (-90, 10), (180, 5), (45, 90)):
        got = js(util_page, f"u.rangeAt(arg, {deg}, {window})", scan)
        assert got == pytest.approx(py_runtime.range_at(scan, deg, window)), (deg, window)
    assert py_runtime.range_at(scan, 0, 30) == 0.5
    assert py_runtime.range_at({"ranges": [], "angle_min": 0, "angle_increment": 0.1,
                                "range_min": 0, "range_max": 1}, 0, 30) == math.inf


def test_velocity_types(util_page, py_runtime):
    for t in ("geometry_msgs/msg/Twist", "geometry_msgs/Twist", "geometry_msgs/msg/TwistStamped",
              "std_msgs/msg/String", "nav_msgs/msg/Odometry"):
        assert js(util_page, f"u.isVelocityType({t!r})") == py_runtime.is_velocity_type(t), t
        if py_runtime.is_velocity_type(t):
            assert js(util_page, f"u.zeroVelocity({t!r})") == py_runtime.zero_velocity(t)


def test_robot_namespace(util_page, py_runtime):
    typed = ["", "/", " / ", "s07", "/s07", "/s07/", "//s07//x/", " s07 "]
    assert js(util_page, "arg.map(u.normNamespace)", typed) == [py_runtime.norm_namespace(t) for t in typed]
    assert py_runtime.norm_namespace("s07/") == "/s07" and py_runtime.norm_namespace(" / ") == ""
    cases = [["", "/turtle1/cmd_vel"], ["/s07", "/turtle1/cmd_vel"], ["s07/", "/spawn"], ["/s07", "odom"],
             ["", "turtle1/pose"]]
    assert js(util_page, "arg.map(([n, x]) => u.withNamespace(n, x))", cases) == [
        py_runtime.with_namespace(n, x) for n, x in cases]
    assert py_runtime.with_namespace("s07/", "/spawn") == "/s07/spawn"
    assert py_runtime.with_namespace("", "turtle1/pose") == "/turtle1/pose"   # a relative name, no namespace
