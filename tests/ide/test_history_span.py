"""History that a person can read: a span picked by its dates and times shows the gateway's rows of
that span alone; a drag or a pinch zooms; the span is saved as CSV (the history API's values) and
the charts as a PNG."""

from __future__ import annotations

import csv
import io
import math
import time

from tests.support.http import api
from tests.support.ide import ARTIFACTS, TABLET, open_teleop
from tests.support.wait import wait_for


def battery_points(gw, start, end):
    return api(gw, "GET", f"/api/history?topic=/battery_state&field=percentage&from={start}&to={end}&step=1")[1]


def test_a_custom_span_zoomed_and_saved_as_csv_and_png(chromium, rover):
    gw, _ = rover
    t0 = math.floor(time.time())
    wait_for(lambda: len(battery_points(gw, t0, time.time())["t"]) >= 8, timeout=30, what="8 s of battery history")
    start, end = t0 + 1, t0 + 7   # a span of the past, by its dates and times

    ctx, page, errors = open_teleop(chromium, gw, viewport=TABLET, has_touch=True, accept_downloads=True)
    try:
        assert not page.is_visible("#plot-from")   # the dates only for a span of one's own
        page.select_option("#plot-span", "custom")
        assert page.is_visible("#plot-from")
        page.wait_for_function("!document.querySelector('#plot-span').dataset.loading")
        page.fill("#plot-from", page.evaluate(f"(async () => (await import('./js/teleop/history.js')).localInput({start}))()"))
        page.fill("#plot-to", page.evaluate(f"(async () => (await import('./js/teleop/history.js')).localInput({end}))()"))
        page.click("#plot-show")
        page.wait_for_function(f"document.querySelector('#plot-span').dataset.to === '{end}' && "
                               "!document.querySelector('#plot-span').dataset.loading && teleop.history.fixed")
        rows = page.evaluate("({t: teleop.history.rows.t, battery: teleop.history.rows.battery})")
        assert rows["t"] and all(start <= t <= end for t in rows["t"]), rows
        # the chart shows that span, and live samples do not join it
        assert page.evaluate("[...teleop.history.charts.values()].every((c) => c.chart.scales.x.min === %d "
                             "&& c.chart.scales.x.max === %d)" % (start, end))
        api_rows = battery_points(gw, start, end)
        # a row per second any plotted series has a point in; the battery's own are the API's
        # (a late sample on a busy machine leaves a second without one: null there)
        mine = [(t, b) for t, b in zip(rows["t"], rows["battery"]) if b is not None]
        assert [round(t, 3) for t, _ in mine] == [round(t, 3) for t in api_rows["t"]]
        assert [v * 100 for v in api_rows["v"]] == [b for _, b in mine]
        n = len(rows["t"])
        wait_for(lambda: page.evaluate("teleop.history.rows.t.length") == n
                 and page.evaluate("Date.now()") > (end + 3) * 1000, timeout=10, what="a few sample intervals")

        # the CSV of the span: a row per point, the battery's column the history API's values
        with page.expect_download() as got:
            page.click("#plot-csv")
        table = list(csv.reader(io.StringIO(got.value.path().read_text())))
        head, body = table[0], table[1:]
        assert head[:2] == ["time", "unix"] and "battery (%)" in head, head
        col = head.index("battery (%)")
        assert [float(r[1]) for r in body] == rows["t"]
        assert [float(r[col]) for r in body if r[col] != ""] == [v * 100 for v in api_rows["v"]]
        assert body[0][0].startswith(time.strftime("%Y-%m-%dT", time.gmtime(start)))

        # the PNG of the charts, axes and legends in it
        with page.expect_download() as got:
            page.click("#plot-png")
        png = got.value.path().read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000, len(png)
        assert got.value.suggested_filename.endswith(".png")

        # a drag across a chart zooms every chart to it; a double-click shows the whole span again
        box = page.locator("#plot .chart .u-over").first.bounding_box()
        y = box["y"] + box["height"] / 2
        page.mouse.move(box["x"] + box["width"] * 0.25, y)
        page.mouse.down()
        page.mouse.move(box["x"] + box["width"] * 0.5, y, steps=5)
        page.mouse.move(box["x"] + box["width"] * 0.75, y, steps=5)
        page.mouse.up()
        page.wait_for_function("teleop.history.zoom !== null")
        lo, hi = page.evaluate("teleop.history.zoom")
        assert start < lo < hi < end and 0.3 * (end - start) < hi - lo < 0.7 * (end - start), (lo, hi)
        assert page.evaluate("[...teleop.history.charts.values()].every((c) => Math.abs(c.chart.scales.x.min - %r) < 1e-6)" % lo)
        with page.expect_download() as got:
            page.click("#plot-csv")
        zoomed = list(csv.reader(io.StringIO(got.value.path().read_text())))[1:]
        assert 0 < len(zoomed) < len(body) and all(lo <= float(r[1]) <= hi for r in zoomed)
        page.dblclick("#plot .chart .u-over >> nth=0")
        page.wait_for_function("teleop.history.zoom === null")

        # two fingers apart on a chart: a narrower span around them
        page.evaluate("""() => {
          const el = document.querySelector('#plot'), r = el.getBoundingClientRect(), y = r.top + 40, mid = r.left + r.width / 2;
          const touches = (d) => [0, 1].map((i) => new Touch({ identifier: i, target: el, clientX: mid + (i ? d : -d), clientY: y }));
          const fire = (type, d) => el.dispatchEvent(new TouchEvent(type, { touches: touches(d), cancelable: true, bubbles: true }));
          fire('touchstart', 20); fire('touchmove', 40); fire('touchmove', 80);
          el.dispatchEvent(new TouchEvent('touchend', { touches: [], bubbles: true }));
        }""")
        lo, hi = page.evaluate("teleop.history.zoom")
        assert start < lo < hi < end and abs((hi - lo) - (end - start) / 4) < 0.5, (lo, hi)
        page.screenshot(path=str(ARTIFACTS / "teleop-history-span.png"))

        # a day: midnight to midnight of the browser's time, the rows of that day in it
        day = page.evaluate("(t) => { const d = new Date(t * 1000); return [d.getFullYear(), d.getMonth() + 1, d.getDate()]"
                            ".map((n) => String(n).padStart(2, '0')).join('-'); }", start)
        page.fill("#plot-day", day)
        page.wait_for_function(f"document.querySelector('#plot-span').dataset.to !== '{end}' && "
                               "!document.querySelector('#plot-span').dataset.loading")
        lo, hi = page.evaluate("teleop.history.fixed")
        assert hi - lo in (86400, 82800, 90000) and page.evaluate(f"new Date({lo} * 1000).getHours()") == 0
        assert lo <= start < hi and page.evaluate("teleop.history.rows.t.length") > 0
        assert not errors, errors
    finally:
        ctx.close()
