""""Make a block" from a topic with list fields (the rover's /scan): the reader offers the
smallest, largest and mean number of a list and its item i; the JavaScript and the Python it
generates give the same answers, in the runtime helpers and on the live robot."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from tests.support.ide import ARTIFACTS, ex, program
from tests.support.wait import wait_for


def js_pick(page, msg, selector, index=0):
    return page.evaluate("""async ([msg, selector, index]) => {
      const u = await import('/runtime/util.js');
      try { const v = u.pick(msg, selector, index); return {v: u.fmt(v)}; } catch (e) { return {error: e.message}; }
    }""", [msg, selector, index])


def py_pick(rt, msg, selector, index=0):
    try:
        return {"v": rt.fmt(rt.pick(msg, selector, index))}
    except Exception as e:
        return {"error": str(e)}


MSG = {"range_max": 10.0, "ranges": [2.5, None, 0.75, 3, None, 9.125], "empty": [], "nones": [None, None],
       "ints": [3, 1, 2], "nested": {"data": [0.1, 0.2, 0.3]}, "flags": [True, 2]}
CASES = [("range_max", 0), ("min:ranges", 0), ("max:ranges", 0), ("mean:ranges", 0), ("item:ranges", 0),
         ("item:ranges", 2), ("item:ranges", -1), ("item:ranges", 1), ("item:ranges", 2.9), ("item:ranges", 6),
         ("item:ranges", -7), ("item:ranges", None), ("min:empty", 0), ("max:empty", 0), ("mean:empty", 0),
         ("min:nones", 0), ("mean:ints", 0), ("min:ints", 0), ("mean:nested.data", 0), ("max:flags", 0),
         ("min:range_max", 0), ("min:nothing", 0), ("nested.data.1", 0)]


def test_pick_is_the_same_in_both_languages(util_page, py_runtime):
    for selector, index in CASES:
        js, py = js_pick(util_page, MSG, selector, index), py_pick(py_runtime, MSG, selector, index)
        assert ("error" in js) == ("error" in py), (selector, index, js, py)
        if "v" in js:
            assert js == py, (selector, index)
    assert py_pick(py_runtime, MSG, "min:ranges") == {"v": "0.75"}
    assert py_pick(py_runtime, MSG, "mean:ranges") == {"v": py_runtime.fmt((2.5 + 0.75 + 3 + 9.125) / 4)}
    assert py_pick(py_runtime, MSG, "min:empty") == {"v": "inf"} and py_pick(py_runtime, MSG, "mean:nones") == {"v": "nan"}
    assert "no item 6" in js_pick(util_page, MSG, "item:ranges", 6)["error"]
    assert "not a list" in js_pick(util_page, MSG, "min:range_max")["error"]


def finite(ranges):
    return [r for r in ranges if r is not None and math.isfinite(r)]


def test_make_a_block_reads_scan_ranges(rover_gateway, rover_ros, ide_factory):
    ide = ide_factory(rover_gateway)
    ide.make_block("read", "/scan", "scan", "my_read_scan")
    options = ide.js("rosgateIde.custom.find((c) => c.json.type === 'my_read_scan').json.args0[0].options")
    values = [v for _, v in options]
    for how in ("min", "max", "mean", "item"):
        assert f"{how}:ranges" in values, values
    assert "range_max" in values and "smallest of ranges" in [t for t, _ in options]

    def reader(selector: str, index: float | None = None, id_: str | None = None) -> dict:
        b = ex.block("my_read_scan", {"FIELD": selector}, id=id_)
        if index is not None:
            b["extraState"] = {"item": True}
            b["inputs"] = {"I": ex.num(index)}
        return ex.log(b)

    prog = {**program(ex.seq(reader("min:ranges"), reader("max:ranges"), reader("mean:ranges"),
                             reader("item:ranges", 0), reader("range_max"))),
            "blocks": ide.js("rosgateIde.custom")}
    ide.js("(p) => rosgateIde.loadProgram(p)", prog)
    js = ide.javascript()
    py = ide.python()
    assert "rt.pick((await rt.latest('/scan', 'sensor_msgs/msg/LaserScan')), 'min:ranges', 0)" in js
    assert "rt.pick((await rt.latest('/scan', 'sensor_msgs/msg/LaserScan')), 'item:ranges', 0)" in js
    assert "rt.log(pick(rt.latest('/scan', 'sensor_msgs/msg/LaserScan'), 'min:ranges', 0))" in py
    # the item input is there only while an item is chosen, and comes back with the program
    assert ide.js("rosgateIde.workspace.getAllBlocks(false).filter((b) => b.type === 'my_read_scan')"
                  ".map((b) => !!b.getInput('I'))") == [False, False, False, True, False]
    ide.js("""() => { const b = rosgateIde.workspace.getAllBlocks(false).find((b) => b.type === 'my_read_scan');
                      b.setFieldValue('item:ranges', 'FIELD'); }""")
    assert ide.js("""rosgateIde.workspace.getAllBlocks(false).find((b) => b.type === 'my_read_scan')
                     .getInputTargetBlock('I')?.getFieldValue('NUM')""") == 0

    # the rover stands still: its scan does not change, so both languages and a direct reading agree
    ide.js("(p) => rosgateIde.loadProgram(p)", prog)
    scan = rover_ros.watch("/scan", "sensor_msgs/msg/LaserScan")
    msg = wait_for(scan.latest, what="a scan")
    ranges = finite(msg["ranges"])
    assert ranges, "the rover sees something"
    ide.run()
    ide.wait_idle(timeout=15)
    logs = ide.logs()
    expect_min, expect_max = min(ranges), max(ranges)
    assert float(logs[0]) == pytest.approx(expect_min, abs=1e-6)
    assert float(logs[1]) == pytest.approx(expect_max, abs=1e-6)
    assert float(logs[2]) == pytest.approx(sum(ranges) / len(ranges), rel=1e-6)
    assert logs[4] == str(msg["range_max"]) or float(logs[4]) == pytest.approx(msg["range_max"])
    path = ARTIFACTS / "scan_reader.py"
    path.write_text(py)
    out = subprocess.run([sys.executable, str(path), "--url", rover_gateway.ws_url],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == logs
    assert not ide.errors, ide.errors
