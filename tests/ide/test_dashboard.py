"""The teleop page's dashboard against the simulated rover, in Chromium: gauges with warning
colours, history plots with their own axes and live legends, history kept across a reload, and
the speed slider and ▲ key within the rover's own limit (its node parameter, 0.8 m/s)."""

from __future__ import annotations

import time

import pytest

from tests.support.ide import ARTIFACTS, PHONE, TABLET, open_teleop
from tests.support.wait import wait_for


def test_gauges_history_and_limits(chromium, rover):
    gw, ros = rover
    cmd = ros.watch("/cmd_vel", "geometry_msgs/msg/Twist")
    ctx, page, errors = open_teleop(chromium, gw, viewport=TABLET, has_touch=True)
    try:
        # from its first sample each plot shows recent time: the span's own, never uPlot's
        # thousand days around a single point
        page.wait_for_function("teleop.history.rows.t.length >= 1")
        spans = page.evaluate("[...teleop.history.charts.values()].map((c) => "
                              "[c.chart.scales.x.min, c.chart.scales.x.max, Date.now() / 1000])")
        assert len(spans) == 3 and all(60 <= hi - lo <= 660 and abs(now - hi) < 120 for lo, hi, now in spans), spans
        # the slider's range is the rover's limit; ▲ at full slider sends exactly that
        page.wait_for_function("document.querySelector('#maxspeed').max === '0.8'")
        assert "0.8 m/s" in page.inner_text("#limits")
        page.fill("#maxspeed", "0.8")
        page.dispatch_event("#maxspeed", "input")
        t0 = time.monotonic()
        page.keyboard.down("ArrowUp")
        wait_for(lambda: len(cmd.since(t0)) >= 25, timeout=10, what="2.5 s of commands")
        page.keyboard.up("ArrowUp")
        wait_for(lambda: cmd.latest()["linear"]["x"] == 0, what="zero after the key")
        sent = [m["linear"]["x"] for _, m in cmd.since(t0)]
        assert max(sent) == pytest.approx(0.8) and all(x <= 0.8 + 1e-9 for x in sent)

        # gauges: battery and both motors, with a level colour each
        page.wait_for_function("['#g-battery', '#g-left', '#g-right'].every((s) => document.querySelector(s).dataset.level === 'ok')")
        assert 0 < float(page.get_attribute("#g-battery", "data-value")) <= 100
        assert 20 < float(page.get_attribute("#g-left", "data-value")) < 90
        ok_colour = page.evaluate("getComputedStyle(document.querySelector('#g-left .g-fill')).stroke")

        # history: one chart per unit, the speed seen while driving, legends with numbers
        page.wait_for_function("teleop.history.rows.speed.some((v) => v > 0.3)", timeout=10000)
        units = page.eval_on_selector_all("#plot .chart", "(cs) => cs.map((c) => c.dataset.unit)")
        assert units == ["°C", "m/s", "%"]
        assert page.eval_on_selector_all("#plot .chart canvas", "(cs) => cs.length") == 3
        page.wait_for_function("teleop.history.rows.battery.some((v) => v > 0)")
        legends = page.eval_on_selector_all("#plot .legend span", "(ss) => ss.map((s) => s.textContent)")
        assert len(legends) == 4 and all(any(ch.isdigit() for ch in t) for t in legends), legends
        page.screenshot(path=str(ARTIFACTS / "teleop-dashboard-tablet.png"))

        # the warning colours: a hot motor turns amber then red, a low battery red
        colours = page.evaluate("""async () => {
          const { gauge } = await import('./js/teleop/dashboard.js');   // the page's own instance
          const probe = document.createElement('div'); document.body.append(probe);
          const g = gauge(probe, { label: 'probe', unit: '°C', min: 20, max: 90, warn: 50, danger: 65 });
          const out = [];
          for (const v of [40, 55, 70]) { g.set(v); out.push([probe.dataset.level, getComputedStyle(probe.querySelector('.g-fill')).stroke]); }
          probe.remove();
          return out;
        }""")
        assert [c[0] for c in colours] == ["ok", "warn", "danger"]
        assert colours[0][1] == ok_colour and len({c[1] for c in colours}) == 3

        # the history survives a reload
        kept = page.evaluate("teleop.history.rows.t.length")
        page.evaluate("teleop.history.save()")
        page.reload()
        page.wait_for_function("document.body?.dataset.connection === 'connected'")
        assert page.evaluate("teleop.history.rows.t.length") >= kept
        assert page.evaluate("teleop.history.rows.speed.some((v) => v > 0.3)")
        page.set_viewport_size(PHONE)
        page.wait_for_function("document.querySelector('#plot').getBoundingClientRect().width < 390")
        page.wait_for_function("teleop.history.rows.t.length > %d" % kept)
        page.screenshot(path=str(ARTIFACTS / "teleop-dashboard-phone.png"), full_page=True)
        assert not errors, errors
    finally:
        ctx.close()


def test_the_gateways_rows_keep_the_pages_newer_samples(chromium, rover):
    """The gateway writes its history every few seconds: rows it sends for the live span end before
    what the page has just shown, and the page's newer samples stay after them."""
    gw, _ = rover
    ctx, page, errors = open_teleop(chromium, gw, viewport=TABLET)
    try:
        page.wait_for_function("teleop.history.rows.t.length >= 1 && teleop.history.series.some((s) => s.id === 'speed')")
        kept = page.evaluate("""() => {
          const h = teleop.history, now = Date.now() / 1000;
          h.series.find((s) => s.id === 'speed').last = 0.7;
          h.sample(now + 1); h.sample(now + 2);                       // what the page showed
          const rows = { t: [now - 2, now - 1] };                     // the gateway's, a little older
          for (const s of h.series) rows[s.id] = [0.1, 0.2];
          h.replace(rows, 600);
          return { t: h.rows.t.map((x) => x - now), speed: h.rows.speed };
        }""")
        t, speed = kept["t"], kept["speed"]
        assert t[:2] == [-2, -1] and speed[:2] == [0.1, 0.2], kept   # the gateway's rows first
        assert t[-2:] == [1, 2] and speed[-2:] == [0.7, 0.7], kept   # then the page's newer samples
        assert all(-1 < x < 1 for x in t[2:-2]), kept                # (and its own ticks between)
        # a span of the past chosen by its dates stays as the gateway gave it
        fixed = page.evaluate("""() => {
          const h = teleop.history, now = Date.now() / 1000;
          h.replace({ t: [now - 3600], speed: [0.3] }, 60, [now - 3660, now - 3540]);
          return h.rows.t.length;
        }""")
        assert fixed == 1
        assert not errors, errors
    finally:
        ctx.close()
