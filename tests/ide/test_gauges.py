"""Gauges by type on the teleop page: every BatteryState, Temperature and JointState a robot has on
its graph gets gauges named by its topic, with the limits of the gateway's --gauges file (a topic, a
glob, a name relative to the robot) or of the robot's own message (a battery's health)."""

from __future__ import annotations

import json
import roslibpy

from tests.support.http import api
from tests.support.ide import ARTIFACTS, TABLET, open_teleop
from tests.support.wait import wait_for

LIMITS = """
["/pack2/battery"]
warn = 80
danger = 60

["/arm/*/temperature"]
warn = 30
danger = 40
max = 60

["arm/joint_states".effort]
max = 10
warn = 5
danger = 8
"""


def test_gauges_found_on_the_graph_with_the_files_limits(chromium, start_gateway, tmp_path):
    limits = tmp_path / "gauges.toml"
    limits.write_text(LIMITS)
    gw = start_gateway("--robot", "rover", "--gauges", str(limits))
    ros = roslibpy.Ros(gw.host, gw.port)
    ros.run(timeout=10)
    pubs = {
        "/pack2/battery": ("sensor_msgs/msg/BatteryState", {"percentage": 0.7, "voltage": 24.1,
                                                             "power_supply_status": 2, "power_supply_health": 2}),
        "/pack3/battery": ("sensor_msgs/msg/BatteryState", {"percentage": 0.9, "power_supply_health": 3}),   # overheat
        "/arm/wrist/temperature": ("sensor_msgs/msg/Temperature", {"temperature": 35.0}),
        "/arm/joint_states": ("sensor_msgs/msg/JointState", {"name": ["shoulder", "elbow"], "position": [0, 0],
                                                              "velocity": [0, 0], "effort": [2.0, -9.0]}),
    }
    topics = {name: roslibpy.Topic(ros, name, type_) for name, (type_, _) in pubs.items()}
    try:
        for t in topics.values():
            t.advertise()
        wait_for(lambda: all(t.is_advertised for t in topics.values()), timeout=10, what="advertised")
        assert api(gw, "GET", "/api/gauges")[1]["limits"]["/pack2/battery"] == {"warn": 80, "danger": 60}

        ctx, page, errors = open_teleop(chromium, gw, viewport=TABLET)

        def keep_publishing():
            for name, (_, msg) in pubs.items():
                topics[name].publish(roslibpy.Message(msg))
        try:
            # every topic found (a JointState's joints: as its first message names them)
            wait_for(lambda: keep_publishing() is None and page.evaluate(
                "document.querySelectorAll('#gauges [data-joint]').length") >= 2 and set(pubs) <= {*page.evaluate(
                "[...document.querySelectorAll('#gauges [data-topic]')].map((g) => g.dataset.topic)")},
                timeout=15, what="a gauge per topic")
            sel = lambda topic, joint=None: f'#gauges [data-topic="{topic}"]' + (f'[data-joint="{joint}"]' if joint else '')

            def levels():
                keep_publishing()
                return page.evaluate("""() => Object.fromEntries([...document.querySelectorAll('#gauges [data-topic]')]
                  .map((g) => [g.dataset.topic + (g.dataset.joint ? ' ' + g.dataset.joint : ''), [g.dataset.level, g.dataset.value]]))""")
            wait_for(lambda: all(levels().get(k, [''])[0] for k in
                                 ["/pack2/battery", "/pack3/battery", "/arm/wrist/temperature",
                                  "/arm/joint_states shoulder", "/arm/joint_states elbow"]),
                     timeout=15, what="every gauge's first value")
            got = levels()
            # named by topic, each with its value
            label = page.text_content(sel("/arm/wrist/temperature") + " .g-label")   # its tail, when long
            assert label.lstrip("…") and "/arm/wrist/temperature".endswith(label.lstrip("…")), label
            assert page.get_attribute(sel("/arm/wrist/temperature"), "title") == "/arm/wrist/temperature"
            assert page.text_content(sel("/pack2/battery") + " .g-label") == "/pack2/battery"
            assert float(got["/pack2/battery"][1]) == 70
            # the file's limits: 70 % is below its warn (80, the page's own: 50); 35 °C above its 30
            assert got["/pack2/battery"][0] == "warn"
            assert got["/arm/wrist/temperature"][0] == "warn"   # the page's default warn is 50 °C
            assert json.loads(page.get_attribute(sel("/arm/wrist/temperature"), "data-limits"))["max"] == 60
            # a relative name in the file: the joints' effort, |effort| against 5 and 8
            assert got["/arm/joint_states shoulder"] == ["ok", "2"]
            assert got["/arm/joint_states elbow"] == ["danger", "9"]
            # the robot's own word: a 90 % battery that overheats is in danger
            assert got["/pack3/battery"] == ["danger", "90"]
            # the rover's own battery and motors keep their gauges, not drawn twice
            assert page.eval_on_selector_all('#gauges [data-topic="/battery_state"]', "(gs) => gs.length") == 1
            # each battery and temperature plotted by its topic too, in its unit's chart
            wait_for(lambda: keep_publishing() is None and page.evaluate(
                "[35, 70].every((v, i) => teleop.history.rows[['/arm/wrist/temperature', '/pack2/battery'][i]]"
                ".some((x) => Math.abs(x - v) < 1e-6))"), timeout=10, what="the plots of the found topics")
            legends = page.eval_on_selector_all("#plot .legend span", "(ss) => ss.map((s) => s.dataset.id)")
            assert {"/arm/wrist/temperature", "/pack2/battery", "/pack3/battery"} <= set(legends), legends
            page.screenshot(path=str(ARTIFACTS / "teleop-gauges-by-type.png"))
            assert not errors, errors
        finally:
            ctx.close()
    finally:
        for t in topics.values():
            t.unadvertise()
        ros.close()
