"""A class through a lesson, in Chromium: --fleet 3 --exclusive-control --allow-runs with one token
per student (and without --auth, one browser per student). A station belongs to its student
through closed tabs; with every station taken a page drives nothing; the teacher's Stop holds
until the owner's Take; Run on robot from the owner's page drives at once and gives her the
robot back. Checked by an independent client signed in as the teacher."""

from __future__ import annotations

import time

import pytest

from tests.support.http import api
from tests.support.ide import ARTIFACTS, PHONE, drive, ex, program
from tests.support.lesson import POSE, TOKENS, TWIST, Teacher, console_says, move, on_station, open_ide, tokens_file
from tests.support.wait import wait_for

GRACE = 1.0   # --claim-grace: how soon a claim lapsed after its tab closed, had it been a tab's


@pytest.fixture
def lesson(start_gateway, tmp_path):
    return start_gateway("--robot", "turtlesim", "--fleet", "3", "--exclusive-control", "--auth", tokens_file(tmp_path),
                         "--allow-runs", "--runs-dir", str(tmp_path / "runs"), "--cmd-timeout", "0",
                         "--claim-grace", str(GRACE))


@pytest.fixture
def teacher(lesson):
    t = Teacher(lesson)
    yield t
    t.close()


def test_a_student_returns_to_her_own_station_and_a_late_one_drives_nothing(lesson, teacher, tablets):
    gw = lesson
    t0 = time.monotonic()
    ada_tablet = tablets(gw, "ada")
    ada = open_ide(ada_tablet, gw)
    on_station(ada, "/s01")
    wait_for(lambda: teacher.owners() == {"/s01": "ada"}, what="/s01 announced as ada's")
    t_ada = time.monotonic() - t0

    # she closes her tablet: her page is gone and the lease with it, the station stays hers
    ada.page.close()
    wait_for(lambda: teacher.driver("/s01") is None, what="ada's page gone")
    closed = time.monotonic()
    bo = open_ide(tablets(gw, "bo"), gw)
    cy = open_ide(tablets(gw, "cy"), gw)
    on_station(bo, "/s02")
    on_station(cy, "/s03")
    # a window past the old lapse of a closed tab's claim (here GRACE) and the gateway's next look
    wait_for(lambda: time.monotonic() - closed > 3 * GRACE + 1, timeout=10, what="the observation window")
    assert all(o.get("/s01") == "ada" for o in teacher.owners_since(closed)), teacher.owners_since(closed)
    t_others = time.monotonic() - t0

    # she comes back (a new page of her browser) to her own station
    ada = open_ide(ada_tablet, gw)
    on_station(ada, "/s01")
    t_back = time.monotonic() - t0

    # a fourth student on a phone: nothing is free; the page says so and drives nothing
    cmd = {ns: teacher.watch(f"{ns}/turtle1/cmd_vel", TWIST) for ns in ("", "/s01", "/s02", "/s03")}
    dee = open_ide(tablets(gw, "dee", PHONE), gw)
    console_says(dee, "No robot for you: all 3 stations are taken")
    assert dee.js("rosgateIde.ns") == "" and dee.js("rosgateIde.robotNs.mine") == ""
    dee.js("(p) => rosgateIde.loadProgram(p)", move())
    dee.page.click("#run")
    console_says(dee, "No robot for you.*\\n.*No robot for you")
    dee.page.wait_for_selector("#run-robot:not([hidden])")
    dee.page.click("#run-robot")
    console_says(dee, "Run on robot: No robot for you")
    teacher.round_trip()
    assert not any(box for box in cmd.values()), {ns: len(b) for ns, b in cmd.items()}
    assert dee.js("rosgateIde.runner.runs") == 0 and dee.js("rosgateIde.runner.errors.size") == 0
    assert api(gw, "GET", "/api/runs", token=TOKENS["teacher"])[1]["runs"] == []
    dee.screenshot("lesson-phone-no-robot")
    t_dee = time.monotonic() - t0

    # the teacher's view names whose each station is
    page = tablets(gw, "teacher").new_page()
    page.goto(gw.http_url + "class")
    page.wait_for_function("document.body?.dataset.tiles === '3'")
    for ns, name in (("/s01", "ada"), ("/s02", "bo"), ("/s03", "cy")):
        page.wait_for_function("([ns, name]) => document.querySelector(`article.tile[data-ns='${ns}'] .holder`)"
                               ".textContent === `${name} drives`", arg=[ns, name])
    page.screenshot(path=str(ARTIFACTS / "lesson-class.png"))
    assert not (ada.errors or bo.errors or cy.errors or dee.errors), ada.errors + bo.errors + cy.errors + dee.errors
    print(f"\nlesson timings (s from start): ada on /s01 {t_ada:.1f}; bo and cy seated, /s01 still ada's "
          f"{t_others:.1f}; ada back on /s01 {t_back:.1f}; dee told nothing is free {t_dee:.1f}")


def test_the_teachers_stop_holds_until_the_owner_takes(lesson, teacher, tablets):
    gw = lesson
    ada_tablet = tablets(gw, "ada")
    ada = open_ide(ada_tablet, gw)
    on_station(ada, "/s01")
    pose = teacher.watch("/s01/turtle1/pose", POSE)
    ada.js("(p) => rosgateIde.loadProgram(p)", program(drive(60, 0.5)))
    ada.run()
    wait_for(lambda: pose and pose[-1][1]["linear_velocity"] > 0, what="the program driving /s01")

    cls = tablets(gw, "teacher").new_page()
    cls.goto(gw.http_url + "class")
    cls.wait_for_function("document.querySelector(\"article.tile[data-ns='/s01'] .holder\")?.textContent === 'ada drives'")
    cls.click("article.tile[data-ns='/s01'] .stop")
    ada.wait_idle(timeout=10)
    console_says(ada, "Stopped by the teacher")
    cls.wait_for_function("document.querySelector(\"article.tile[data-ns='/s01'] .holder\").textContent === \"ada's station (stopped)\"")
    wait_for(lambda: pose[-1][1]["linear_velocity"] == 0 and pose[-1][1]["angular_velocity"] == 0,
             what="the turtle standing still")

    # pages pointed at /s01 try for 10 s: bo's tablet, and ada's own page reloaded, press Run
    bo = open_ide(tablets(gw, "bo"), gw, "?ns=/s01")
    bo.page.wait_for_function("rosgateIde.ns === '/s01' && rosgateIde.lease.available")
    ada2 = open_ide(ada_tablet, gw)
    ada2.page.wait_for_function("rosgateIde.robotNs.mine === '/s01' && rosgateIde.lease.halted")
    still = dict(pose[-1][1])
    t_window = time.monotonic()
    for page in (bo, ada2, ada):
        page.js("(p) => rosgateIde.loadProgram(p)", move(2))
        page.page.click("#run")
    console_says(ada, "The teacher stopped /s01: press Take to drive it again")
    console_says(ada2, "The teacher stopped /s01: press Take to drive it again")
    wait_for(lambda: time.monotonic() - t_window > 10, timeout=15, what="the 10 s window")
    teacher.round_trip()
    moved = [m for t, m in pose if t >= t_window and (abs(m["x"] - still["x"]) > 1e-6 or abs(m["y"] - still["y"]) > 1e-6
                                                      or abs(m["theta"] - still["theta"]) > 1e-6)]
    assert not moved, f"the stopped turtle moved: {moved[:3]}"
    assert teacher.driver("/s01") is None
    # the refusal is said in her console, once for the stop, not on her blocks
    assert ada.console_text().count("Stopped by the teacher") == 1
    assert ada.js("rosgateIde.runner.errors.size") == 0 and ada2.js("rosgateIde.runner.errors.size") == 0
    ada2.screenshot("lesson-stopped-tablet")

    # her Take resumes
    ada2.page.click("#take")
    ada2.page.wait_for_function("rosgateIde.lease.state === 'you' && !rosgateIde.lease.halted")
    t_take = time.monotonic()
    ada2.page.click("#run")
    wait_for(lambda: any(abs(m["x"] - still["x"]) > 0.1 for t, m in pose if t >= t_take), what="moving after Take")
    assert not (ada.errors or ada2.errors), ada.errors + ada2.errors


def test_run_on_robot_from_the_owners_page_takes_and_gives_back_her_robot(lesson, teacher, tablets):
    gw = lesson
    ada = open_ide(tablets(gw, "ada"), gw)
    on_station(ada, "/s01")
    ada.page.wait_for_selector("#run-robot:not([hidden])")
    ada.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(
        ex.block("ros_log", inputs={"VALUE": ex.text("on the robot")}), drive(0.5, 0.5))))
    t0 = time.monotonic()
    ada.page.click("#run-robot")
    console_says(ada, "on the robot\\n")
    ran = time.monotonic() - t0
    wait_for(lambda: teacher.drove("/s01", lambda d: d["run"] and d["owner"]), what="her run driving her station")
    console_says(ada, "run r[0-9a-f]+ finished")
    ada.page.wait_for_function("rosgateIde.lease.state === 'you'")    # hers again, without Take
    text = ada.console_text()
    assert "pick a free robot" not in text and "holds the driver lease" not in text and "ada (client" not in text, text
    assert teacher.driver("/s01") == "ada"

    # another student's run on her station is refused
    status, body = api(gw, "POST", "/api/runs", {"source": ada.python(), "ns": "/s01"}, token=TOKENS["bo"])
    assert status == 409 and "ada's station" in body["error"], body
    assert not ada.errors, ada.errors
    print(f"\nRun on robot: its first output {ran:.1f} s after the press")


def test_without_auth_a_station_is_a_browsers(start_gateway, tablets):
    gw = start_gateway("--robot", "turtlesim", "--fleet", "2", "--exclusive-control", "--claim-grace", str(GRACE))
    first = tablets(gw, None)
    ide = open_ide(first, gw)
    on_station(ide, "/s01")
    ide.page.close()
    other = open_ide(tablets(gw, None), gw)
    on_station(other, "/s02")
    closed = time.monotonic()
    wait_for(lambda: time.monotonic() - closed > 3 * GRACE + 1, timeout=10, what="the observation window")
    again = open_ide(first, gw)
    on_station(again, "/s01")
    third = open_ide(tablets(gw, None), gw)
    console_says(third, "No robot for you: all 2 stations are taken")
    assert third.js("rosgateIde.ns") == ""
