"""The teleop page's plots from the gateway's history: a browser that was never open during a
drive shows that drive when it asks for the last hour."""

from __future__ import annotations

import time

import roslibpy

from tests.support.ide import ARTIFACTS, TABLET, open_teleop
from tests.support.wait import wait_for


def test_a_fresh_browser_shows_the_earlier_drive_over_an_hour(chromium, rover):
    gw, ros = rover
    cmd = roslibpy.Topic(ros.ros, '/cmd_vel', 'geometry_msgs/msg/Twist')
    cmd.advertise()
    t0 = time.time()
    while time.time() - t0 < 14:   # no page is open meanwhile; at least 3 of the hour's 5 s steps
        cmd.publish(roslibpy.Message({'linear': {'x': 0.5, 'y': 0, 'z': 0}, 'angular': {'x': 0, 'y': 0, 'z': 0.4}}))
        time.sleep(0.1)
    cmd.unadvertise()
    drove_until = time.time()
    wait_for(lambda: time.time() > drove_until + 3, timeout=10, what="the gateway's last batch")

    ctx, page, errors = open_teleop(chromium, gw, viewport=TABLET)   # a new context: nothing in its storage
    try:
        opened = page.evaluate("Date.now() / 1000")
        page.select_option("#plot-span", "3600")
        page.wait_for_function("document.querySelector('#plot-span').dataset.loaded > 0 && "
                               "!document.querySelector('#plot-span').dataset.loading")
        # the rows and what the charts draw, read at one instant (a live sample a second adds a row)
        rows = page.evaluate("({t: teleop.history.rows.t, speed: teleop.history.rows.speed, "
                             "battery: teleop.history.rows.battery, window: teleop.history.window, "
                             "drawn: [...teleop.history.charts.values()].map((c) => c.chart.data[0].length)})")
        assert rows['window'] == 3600
        before = [v for t, v in zip(rows['t'], rows['speed']) if t < opened - 1 and v is not None]
        assert len(before) >= 3 and max(before) > 0.3            # the drive, from before the page opened
        assert min(rows['t']) < drove_until
        assert any(v is not None and 0 < v <= 100 for v in rows['battery'])
        # the chart draws those rows, and live samples keep coming after them
        drawn = rows['drawn']
        assert drawn and all(n == len(rows['t']) for n in drawn), (drawn, len(rows['t']))
        # each step's min and max around its mean, drawn as a band behind the line
        band = page.evaluate("""(() => {
          const h = teleop.history, c = [...h.charts.values()].find((c) => c.div.dataset.unit === 'm/s');
          return { bands: c.chart.bands.length, series: c.chart.series.length, v: h.rows.speed,
                   lo: h.rows['speed:min'], hi: h.rows['speed:max'] };
        })()""")
        assert band['bands'] == 1 and band['series'] == 4, band   # x, the speed, its max and its min
        steps = [(lo, v, hi) for lo, v, hi in zip(band['lo'], band['v'], band['hi']) if v is not None and lo is not None]
        assert len(steps) >= 3 and all(lo - 1e-9 <= v <= hi + 1e-9 for lo, v, hi in steps), steps
        n = len(rows['t'])
        page.wait_for_function(f"teleop.history.rows.t.length > {n}")
        page.screenshot(path=str(ARTIFACTS / "teleop-history-hour.png"))
        assert not errors, errors
    finally:
        ctx.close()
