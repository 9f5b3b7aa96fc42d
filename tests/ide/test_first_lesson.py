"""The first lesson as docs/teacher.md tells it, in Chromium: a token per student, the guide's flags,
/class for the teacher; a student on a 1024x768 tablet and on a 390x844 phone. The teacher's
Release (a tile's, and Release all) sticks on the student's open pages; one person's IDE and
teleop pages share her station; the IDE follows its console and shows the teleop page's banner;
Stop all leaves free stations ready; tiles show the present; the teleop page shows what the
robot has. Checked by an independent client signed in as the teacher."""

from __future__ import annotations

import time

import pytest

from tests.support.ide import ARTIFACTS, PHONE, ex, program
from tests.support.lesson import TWIST, Teacher, console_says, move, on_station, open_ide, tokens_file
from tests.support.wait import wait_for

TABLET = {"width": 1024, "height": 768}
POSE = "turtlesim/msg/Pose"
WINDOW = 15.0      # s the released station is watched for a page of hers taking it back
# the guide's globs (docs/teacher.md, "Start the class gateway")
GLOBS = ("--topics-glob", "['/s[0-9][0-9]/*', '/rosgate/*', '/client_count']",
         "--services-glob", "['/rosapi/*', '/s[0-9][0-9]/*', '/fleet/*']")


@pytest.fixture
def lesson(start_gateway, tmp_path):
    # the guide's flags, three stations (--allow-runs is left to tests/ide/test_class_lesson.py)
    return start_gateway("--robot", "turtlesim", "--fleet", "3", "--exclusive-control", "--auth", tokens_file(tmp_path),
                         "--recordings-dir", str(tmp_path / "recordings"), *GLOBS)


@pytest.fixture
def teacher(lesson):
    t = Teacher(lesson)
    yield t
    t.close()


def open_teleop(ctx, gw):
    page = ctx.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(gw.http_url + "teleop")
    page.wait_for_function("document.body?.dataset.ready === 'true' "
                           "&& document.body.dataset.connection === 'connected'")
    page.errors = errors
    return page


def teleop_on(page, ns: str, more: str = "true"):
    """The teleop page on its person's station ns (a first claim reloads the page under it)."""
    page.wait_for_function(f"window.teleop && !document.body.dataset.reloading "
                           f"&& document.body.dataset.connection === 'connected' "
                           f"&& teleop.robotNs.mine === '{ns}' && ({more})", timeout=15000)


def open_class(ctx, gw):
    page = ctx.new_page()
    page.goto(gw.http_url + "class")
    page.wait_for_function("document.body?.dataset.tiles === '3'")
    return page


def holder_is(cls, ns: str, text: str):
    cls.wait_for_function("([ns, t]) => document.querySelector(`article.tile[data-ns='${ns}'] .holder`)"
                          ".textContent === t",
                          arg=[ns, text], timeout=15000)


def moving_since(box: list, t0: float) -> list:
    return [m for t, m in box if t >= t0 and (m["linear"]["x"] or m["angular"]["z"])]


def notice(page) -> str:
    return page.evaluate("(() => { const n = document.querySelector('#notice');"
                         " return n.hidden ? '' : n.textContent; })()")


def try_to_drive_for(teleop, ide, seconds: float):
    """Her teleop page holds ▲ (and taps it) and her IDE presses Run, for `seconds`."""
    ide.js("(p) => rosgateIde.loadProgram(p)", move(2))
    t0 = time.monotonic()
    teleop.keyboard.down("ArrowUp")
    try:
        while time.monotonic() - t0 < seconds:
            teleop.click("#keys [data-key=up]")
            ide.page.click("#run")
            teleop.wait_for_timeout(1500)
    finally:
        teleop.keyboard.up("ArrowUp")


def test_the_teachers_release_sticks_on_her_open_pages(lesson, teacher, tablets):  # noqa: F811
    gw = lesson
    ide = open_ide(tablets(gw, "ada", TABLET), gw)
    on_station(ide, "/s01")
    teleop = open_teleop(tablets(gw, "ada", PHONE), gw)        # her phone: the same person
    teleop_on(teleop, "/s01")
    cmd = teacher.watch("/s01/turtle1/cmd_vel", TWIST)
    cls = open_class(tablets(gw, "teacher"), gw)
    asked = []
    cls.on("dialog", lambda d: (asked.append(d.message), d.accept()))

    said = {}
    for how in ("tile", "all"):
        # Take, unless her page drives already: one step in the page, since its claim may win the lease
        # between a look from here and a click
        teleop.evaluate("teleop.lease.state === 'you' || document.querySelector('#take').click()")
        teleop.wait_for_function("teleop.lease.state === 'you'")
        holder_is(cls, "/s01", "ada drives")
        t_drive = time.monotonic()
        teleop.keyboard.down("ArrowUp")
        wait_for(lambda: moving_since(cmd, t_drive), what="her teleop page driving /s01")
        teleop.keyboard.up("ArrowUp")

        t_click = time.monotonic()
        if how == "tile":
            cls.click("article.tile[data-ns='/s01'] .release")
        else:
            cls.click("#release-all")
        teleop.wait_for_function("/released \\/s01/.test(document.querySelector('#notice').textContent)")
        said[how] = time.monotonic() - t_click
        holder_is(cls, "/s01", "free")
        ide.page.wait_for_function("/released \\/s01/.test(document.querySelector('#notice').textContent)")
        teacher.round_trip()
        t_released = time.monotonic()
        try_to_drive_for(teleop, ide, WINDOW)
        teacher.round_trip()
        drove = moving_since(cmd, t_released)
        assert not drove, f"Release ({how}): her page drove /s01: {drove[:3]}"
        assert "/s01" not in teacher.owners() and teacher.driver("/s01") is None, (how, teacher.owners())
        assert "released /s01" in notice(teleop) and "Claim a robot" in notice(teleop)
        assert teleop.evaluate("teleop.lease.state") != "you" and teleop.evaluate("teleop.robotNs.mine") == ""
        assert ide.js("rosgateIde.runner.runs") == 0 and ide.js("rosgateIde.runner.errors.size") == 0
        holder_is(cls, "/s01", "free")
        teleop.screenshot(path=str(ARTIFACTS / f"lesson-released-{how}-phone.png"))
        ide.screenshot(f"lesson-released-{how}-tablet")
        # she claims /s01 again (the robot field): hers to drive
        teleop.fill("#ns", "/s01")
        teleop.dispatch_event("#ns", "change")
        teleop.wait_for_function("teleop.robotNs.mine === '/s01' && !teleop.robotNs.lost")
        teleop.evaluate("document.activeElement.blur()")     # the keys drive, not type
    assert asked and "Release every station" in asked[0]
    print(f"\nthe teleop page said it was released {said['tile']:.2f} s after the tile's Release, "
          f"{said['all']:.2f} s after Release all (its confirmation accepted); "
          f"{WINDOW:.0f} s of ▲ and Run moved nothing")
    assert not teleop.errors and not ide.errors, teleop.errors + ide.errors


def test_one_persons_pages_drive_her_station_alternately(lesson, teacher, tablets):  # noqa: F811
    gw = lesson
    ide = open_ide(tablets(gw, "bo", TABLET), gw)
    on_station(ide, "/s01")
    teleop = open_teleop(tablets(gw, "bo", PHONE), gw)
    teleop_on(teleop, "/s01", "teleop.lease.state === 'yours'")
    pose = teacher.watch("/s01/turtle1/pose", POSE)
    cmd = teacher.watch("/s01/turtle1/cmd_vel", TWIST)
    wait_for(lambda: pose, what="a pose")
    ide.js("(p) => rosgateIde.loadProgram(p)", move(0.5))
    for turn in range(2):
        t0 = time.monotonic()
        ide.run()
        ide.wait_idle(timeout=20)
        assert "finished" in ide.console_text().splitlines()[-1], ide.console_text()
        wait_for(lambda: any(abs(m["linear_velocity"]) > 0 for t, m in pose if t >= t0),
                 what=f"the IDE driving ({turn})")
        t1 = time.monotonic()
        teleop.keyboard.down("ArrowUp")
        wait_for(lambda: moving_since(cmd, t1), what=f"the teleop page driving ({turn})")
        wait_for(lambda: any(abs(m["linear_velocity"]) > 0 for t, m in pose if t >= t1 + 0.3), what="moving")
        teleop.keyboard.up("ArrowUp")
        teleop.wait_for_function("teleop.timer === null")
    assert notice(teleop) == "", notice(teleop)
    # on the phone the badge says her other page drives and leaves Take in sight
    ide.run()
    ide.wait_idle(timeout=20)
    teleop.wait_for_function("teleop.lease.state === 'yours'")
    take = teleop.evaluate("(() => { const r = document.querySelector('#take').getBoundingClientRect();"
                           " return {r: r.right, w: r.width, h: r.height}; })()")
    assert teleop.is_visible("#take") and take["w"] > 30 and take["r"] <= PHONE["width"], take
    assert teleop.evaluate("document.documentElement.scrollWidth") <= PHONE["width"]
    teleop.screenshot(path=str(ARTIFACTS / "teleop-phone-another-page.png"))
    assert ide.js("rosgateIde.runner.errors.size") == 0
    text = ide.console_text()
    assert "is driving" not in text and "refused" not in text and "pick a free robot" not in text, text
    assert notice(ide.page) == ""
    assert not teleop.errors and not ide.errors, teleop.errors + ide.errors


def test_the_ide_follows_its_console_and_shows_the_stopped_banner(lesson, teacher, tablets):  # noqa: F811
    gw = lesson
    for who, viewport in (("ada", TABLET), ("bo", PHONE)):
        ide = open_ide(tablets(gw, who, viewport), gw)
        ns = "/s01" if who == "ada" else "/s02"
        on_station(ide, ns)
        logs = [{**ex.log(ex.text(f"line {i}"))} for i in range(40)]
        ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.seq(*logs, ex.block("turtle_drive", id="drive", inputs={
            "TURTLE": ex.text("turtle1"), "SPEED": ex.num(0.5), "TURN": ex.num(0), "SECONDS": ex.num(60)}))))
        ide.run()
        ide.page.wait_for_function("rosgateIde.console.logs().length === 40")
        control = teacher.roslibpy.Topic(teacher.ros, "/rosgate/control", "std_msgs/msg/String")
        control.publish(teacher.roslibpy.Message({"data": f"stop {ns}"}))
        ide.wait_idle(timeout=10)
        console_says(ide, "Stopped by the teacher")
        ide.page.wait_for_function("/Stopped by the teacher/.test(document.querySelector('#notice').textContent)"
                                   " && !document.querySelector('#notice').hidden")
        # the newest line comes in sight, inside the console's box (the banner above it shrinks the
        # box meanwhile: the console scrolls again in the frame after)
        ide.page.wait_for_function("""() => {
          const box = document.querySelector('#console').getBoundingClientRect();
          const r = document.querySelector('#console-lines').lastElementChild.getBoundingClientRect();
          return box.top <= r.top && r.bottom <= box.bottom + 1;
        }""", timeout=5000)
        seen = ide.js("""() => {
          const box = document.querySelector('#console').getBoundingClientRect();
          const last = document.querySelector('#console-lines').lastElementChild;
          const r = last.getBoundingClientRect();
          const c = document.querySelector('#console');
          return {text: last.textContent, top: r.top, bottom: r.bottom, boxTop: box.top, boxBottom: box.bottom,
                  scrolls: c.scrollHeight > c.clientHeight};
        }""")
        assert seen["scrolls"], seen                     # more lines than the box holds
        assert seen["boxTop"] <= seen["top"] and seen["bottom"] <= seen["boxBottom"] + 1, seen
        assert "stopped" in seen["text"].lower() or "Stopped by the teacher" in seen["text"], seen
        ide.page.evaluate("document.querySelector('#console').scrollIntoView()")
        ide.screenshot(f"lesson-console-stopped-{who}")
        take = ide.js("(() => { const r = document.querySelector('#take').getBoundingClientRect();"
                      " return {r: r.right, w: r.width}; })()")
        assert ide.page.is_visible("#take") and take["w"] > 30 and take["r"] <= viewport["width"], take
        # Take: the banner goes, the robot is hers again
        ide.page.click("#take")
        ide.page.wait_for_function("document.querySelector('#notice').hidden")
        assert not ide.errors, ide.errors


def bo_on_s01_and_the_class(gw, tablets):
    """bo's IDE on a tablet, on station /s01, and the teacher's class view."""
    bo = open_ide(tablets(gw, "bo", TABLET), gw)
    on_station(bo, "/s01")
    return bo, open_class(tablets(gw, "teacher"), gw)


def test_stop_all_leaves_a_free_station_ready(lesson, teacher, tablets):  # noqa: F811
    gw = lesson
    bo, cls = bo_on_s01_and_the_class(gw, tablets)
    holder_is(cls, "/s01", "bo drives")
    cls.click("#stop-all")
    holder_is(cls, "/s01", "bo's station (stopped)")
    teacher.round_trip()
    with teacher.lock:
        halted = dict(teacher.drivers[-1]["halted"])
    assert list(halted) == ["/s01"], halted
    # a student arriving after Stop all gets a free station and drives it, no Take needed
    cy = open_ide(tablets(gw, "cy", PHONE), gw)
    on_station(cy, "/s02")             # (watched before her claim, /s02 would count as in use)
    pose = teacher.watch("/s02/turtle1/pose", POSE)
    wait_for(lambda: pose, what="a pose of /s02")
    t0 = time.monotonic()
    cy.js("(p) => rosgateIde.loadProgram(p)", move(1))
    cy.run()
    cy.wait_idle(timeout=20)
    assert any(abs(m["linear_velocity"]) > 0 for t, m in pose if t >= t0), "the free station did not drive"
    assert cy.js("rosgateIde.runner.errors.size") == 0 and notice(cy.page) == ""
    holder_is(cls, "/s02", "cy drives")
    assert not cy.errors, cy.errors


def test_tiles_show_the_present(lesson, teacher, tablets):  # noqa: F811
    gw = lesson
    bo, cls = bo_on_s01_and_the_class(gw, tablets)
    tile = "article.tile[data-ns='/s01']"
    bad = ex.block("ros_call_service_stmt", {"SERVICE": "/no_such_service", "TYPE": "std_srvs/srv/Empty"}, id="bad")
    bo.js("(p) => rosgateIde.loadProgram(p)", program(bad, name="broken"))
    bo.run()
    bo.wait_idle(timeout=15)
    cls.wait_for_function(f"document.querySelector(\"{tile}\").hasAttribute('data-error')", timeout=15000)
    assert "/no_such_service" in cls.inner_text(f"{tile} .error")
    # the teacher's stop is no error of the student's program
    cls.click(f"{tile} .stop")
    holder_is(cls, "/s01", "bo's station (stopped)")
    bo.page.wait_for_function("!document.querySelector('#notice').hidden")
    cls.wait_for_timeout(2500)                         # past the page's report debounce
    assert "Stopped" not in cls.inner_text(f"{tile} .error")
    # her Take clears the error
    bo.page.click("#take")
    cls.wait_for_function(f"!document.querySelector(\"{tile}\").hasAttribute('data-error')", timeout=15000)
    assert cls.inner_text(f"{tile} .error") == ""
    # a new program clears it too
    bo.run()
    bo.wait_idle(timeout=15)
    cls.wait_for_function(f"document.querySelector(\"{tile}\").hasAttribute('data-error')", timeout=15000)
    bo.js("(p) => rosgateIde.loadProgram(p)", move(0.1))
    cls.wait_for_function(f"!document.querySelector(\"{tile}\").hasAttribute('data-error')", timeout=15000)
    # released, the station is free: no program, no error, no state of another station
    cls.on("dialog", lambda d: d.accept())
    cls.click("#release-all")
    holder_is(cls, "/s01", "free")
    assert cls.inner_text(f"{tile} .program") == "" and cls.inner_text(f"{tile} .state") == "no program"
    for ns in ("/s02", "/s03"):
        assert not cls.evaluate(f"document.querySelector(\"article.tile[data-ns='{ns}']\").hasAttribute('data-error')")
    cls.screenshot(path=str(ARTIFACTS / "lesson-class-after-release-all.png"))
    assert not bo.errors, bo.errors


def test_a_turtlesim_teleop_page_shows_the_world_and_no_empty_camera(lesson, teacher, tablets,  # noqa: F811
                                                                     start_gateway):
    gw = lesson
    for viewport in (PHONE, TABLET):
        ctx = tablets(gw, "ada", viewport)
        teleop = open_teleop(ctx, gw)
        teleop_on(teleop, "/s01")
        teleop.wait_for_function("teleop.world && (teleop.world.summary().robots || 0) >= 1", timeout=30000)
        teleop.wait_for_function("document.querySelector('#notice').hidden")      # nothing holds it
        assert teleop.is_visible("#world") and not teleop.is_visible("#camera-card")
        assert not teleop.is_visible("#battery-card")
        assert teleop.evaluate("teleop.world.topic") == "/s01/world/markers"
        box = teleop.evaluate("(() => { const r = document.querySelector('#world').getBoundingClientRect();"
                              " return {w: r.width, h: r.height, top: r.top}; })()")
        assert box["w"] > 100 and box["h"] > 100, box
        if viewport is PHONE:
            # the world and the whole joystick in view; the driving badge leaves Take visible
            joy = teleop.evaluate("document.querySelector('#joystick').getBoundingClientRect().bottom")
            assert box["top"] >= 0 and joy <= PHONE["height"], (box, joy)
            stop = teacher.roslibpy.Topic(teacher.ros, "/rosgate/control", "std_msgs/msg/String")
            stop.publish(teacher.roslibpy.Message({"data": "stop /s01"}))   # Take shows
            teleop.wait_for_function("!document.querySelector('#take').hidden")
            take = teleop.evaluate("(() => { const r = document.querySelector('#take').getBoundingClientRect();"
                                   " return {l: r.left, r: r.right, w: r.width, h: r.height}; })()")
            assert teleop.is_visible("#take") and take["w"] > 30 and take["r"] <= PHONE["width"], take
            assert teleop.evaluate("document.documentElement.scrollWidth") <= PHONE["width"]
            teleop.screenshot(path=str(ARTIFACTS / "teleop-turtlesim-phone-stopped.png"))
            teleop.click("#take")
            teleop.wait_for_function("teleop.lease.state === 'you'")
        teleop.screenshot(path=str(ARTIFACTS / f"teleop-turtlesim-{'phone' if viewport is PHONE else 'tablet'}.png"))
        assert not teleop.errors, teleop.errors
        ctx.close()
    # a rover has a camera and a battery: those are shown
    rover = start_gateway("--robot", "rover")
    ctx = tablets(rover, None, PHONE)
    page = open_teleop(ctx, rover)
    page.wait_for_function("!document.querySelector('#camera-card').hidden "
                           "&& !document.querySelector('#battery-card').hidden",
                           timeout=15000)
    page.wait_for_function("teleop.frames > 0", timeout=30000)
    assert page.is_visible("#world")
