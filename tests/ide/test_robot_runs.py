"""The IDE's "Run on robot" button and the record button, in Chromium against live gateways."""

from __future__ import annotations

import json
import time
import urllib.request
from pathlib import Path

import pytest

from tests.support.http import api
from tests.support.ide import drive, ex, moving, program
from tests.support.ros import RosClient
from tests.support.runs import ended
from tests.support.wait import wait_for


def log(text: str) -> dict:
    return ex.block("ros_log", inputs={"VALUE": ex.text(text)})


@pytest.fixture(scope="module")
def runs_gateway(start_gateway, tmp_path_factory):
    return start_gateway("--robot", "turtlesim", "--allow-runs",
                         "--runs-dir", str(tmp_path_factory.mktemp("runs")),
                         "--record", str(tmp_path_factory.mktemp("recordings")), "--record-topics", "/nothing")


@pytest.fixture
def runs_ros(runs_gateway):
    with RosClient(runs_gateway) as client:
        yield client


def console_has(ide, text: str) -> bool:
    return text in ide.console_text()


def test_run_on_robot_streams_output_and_stop_stops_it(runs_gateway, runs_ros, ide_factory):
    ide = ide_factory(runs_gateway)
    ide.page.wait_for_selector("#run-robot:not([hidden])", timeout=10000)
    cmd = runs_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")

    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(log("hello from the robot"), drive(0.5), log("bye"))))
    ide.page.click("#run-robot")
    wait_for(lambda: console_has(ide, "finished"), 60, what="the run to finish")
    text = ide.console_text()
    assert "no blocks are highlighted" in text
    assert text.index("hello from the robot") < text.index("bye") < text.index("finished")
    assert moving(cmd)
    assert ide.js("document.querySelectorAll('.blocklyHighlighted, .blocklySelected').length") == 0

    # a long one: Stop ends it and the robot gets its zero command at once
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(log("driving"), drive(60))))
    ide.page.click("#run-robot")
    wait_for(lambda: console_has(ide, "driving"), 60, what="the long run's output")
    t0 = time.monotonic()
    wait_for(lambda: moving(cmd, t0), 10, what="the long run driving")

    # a second page opened now shows the run and re-attaches to its output
    other = ide_factory(runs_gateway)
    wait_for(lambda: "is running on the robot" in other.console_text() and "driving" in other.console_text(), 20,
             what="the reopened page re-attaching")

    t1 = time.monotonic()
    ide.page.click("#stop")
    stopped = wait_for(lambda: next((t for t, m in cmd.since(t1) if m["linear"]["x"] == 0), None),
                       what="zero cmd_vel after Stop")
    wait_for(lambda: console_has(ide, "stopped") and console_has(other, "stopped"), 20, what="both pages told")
    assert ide.js("document.body.dataset.robotRun") == "idle"
    assert all(m["linear"]["x"] == 0 for t, m in cmd.since(stopped))
    assert not ide.errors and not other.errors, ide.errors + other.errors


PY_TEXT = """from rosgate_runtime import *


def main():
    rt.log('text on the robot')
    rt.drive('/turtle1/cmd_vel', 'geometry_msgs/msg/Twist', {'linear': {'x': 0.5}}, 0.5)


if __name__ == '__main__':
    run(main)
"""


def test_a_python_text_program_runs_on_the_robot(runs_gateway, runs_ros, ide_factory):
    """"Run on robot" runs a Python text program as it is (the runtime carried on its import line)."""
    ide = ide_factory(runs_gateway)
    ide.page.wait_for_selector("#run-robot:not([hidden])", timeout=10000)
    cmd = runs_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
    ide.js("(p) => rosgateIde.loadProgram(p)", {"format": "rosgate-program", "version": 1, "kind": "text",
                                                "lang": "python", "name": "typed", "text": PY_TEXT})
    ide.page.wait_for_selector(".cm-content")
    ide.page.click("#run-robot")
    wait_for(lambda: console_has(ide, "finished"), 60, what="the text run to finish")
    text = ide.console_text()
    assert "text on the robot" in text and "failed" not in text, text
    assert moving(cmd)


def test_a_program_saved_from_the_library_dialog_runs_on_the_robot_by_name(runs_gateway, runs_ros, ide_factory):
    ide = ide_factory(runs_gateway)
    cmd = runs_ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(log("saved in the library"), drive(0.5))))
    ide.page.fill("#name", "square by name")
    ide.page.dispatch_event("#name", "change")
    ide.page.click("#library")
    ide.page.click("#library-save")
    ide.page.locator("#library-list .lib-open", has_text="square by name").wait_for()
    ide.page.click("#library-close")
    stored = json.loads((Path(runs_gateway.programs_dir) / "square by name.json").read_text())
    assert stored["python"] == ide.python() and stored["workspace"] == ide.workspace()

    status, run = api(runs_gateway, "POST", "/api/runs", {"program": "square by name"})
    assert status == 201, run
    assert run["name"] == "square by name"
    final = ended(runs_gateway, run["id"])
    assert final["state"] == "finished", final
    assert "saved in the library" in final["output"]
    assert moving(cmd)
    assert not ide.errors, ide.errors


def test_button_hidden_without_allow_runs(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway)
    ide.page.wait_for_function("document.body?.dataset.robotRuns === 'off'", timeout=10000)
    assert ide.page.is_hidden("#run-robot")


@pytest.mark.parametrize("page", ["ide", "teleop"])
def test_record_button_shows_time_and_size_and_lists_the_download(runs_gateway, ide_factory, page):
    ide = ide_factory(runs_gateway)
    tab = ide.page
    if page == "teleop":
        tab = tab.context.new_page()
        tab.on("pageerror", lambda e: ide.errors.append(str(e)))
        tab.goto(runs_gateway.http_url + "teleop")
    tab.wait_for_selector("#rec", timeout=10000)
    tab.evaluate("rosgateRecorder.topics.value = '/turtle1/pose'")
    tab.click("#rec")
    tab.wait_for_function("document.querySelector('#rec').textContent.includes('KB')", timeout=15000)
    label = tab.inner_text("#rec")
    assert label.startswith("■ 0:0") and "·" in label, label
    tab.click("#rec")
    tab.wait_for_function("document.body?.dataset.recording === 'off'", timeout=10000)
    tab.click("#recordings")
    link = tab.wait_for_selector("#rec-list a[download]", timeout=10000)
    with urllib.request.urlopen(link.evaluate("a => a.href"), timeout=10) as res:
        assert res.read(8) == b"\x89MCAP0\r\n"
    assert not ide.errors, ide.errors
