"""The booking panel (ide/js/lab/booking.js) in Chromium: the time left in one's slot and the warnings
at 5 minutes and at 1 on the teleop page, a slot booked from the form and shown in the browser's
time zone, the teacher's timetable of every station in /class; and the teleop page of a person
with no free station saying so (the "Claiming a robot…" notice no longer overwrites it)."""

from __future__ import annotations

import datetime
import re
import time
import zoneinfo

import pytest
import roslibpy

from tests.support.http import api
from tests.support.ide import ARTIFACTS

TOKENS = {"teacher": "teacher-token-b001", "ada": "ada-token-b002", "bo": "bo-token-b003", "cy": "cy-token-b004"}
ZONE = "Asia/Tokyo"


@pytest.fixture(scope="module")
def lab(start_gateway, tmp_path_factory):
    tokens = tmp_path_factory.mktemp("booking-auth") / "tokens.toml"
    tokens.write_text("".join(
        f'[[tokens]]\nname = "{name}"\nrole = "{"admin" if name == "teacher" else "operator"}"\ntoken = "{token}"\n\n'
        for name, token in TOKENS.items()))
    return start_gateway("--robot", "turtlesim", "--fleet", "2", "--exclusive-control", "--auth", str(tokens),
                         "--booking", "--slot-minutes", "10", "--station-reset", "reset")


def signed_in(chromium, gw, who: str, **kw):
    ctx = chromium.new_context(viewport={"width": 1280, "height": 820}, **kw)
    r = ctx.request.post(gw.http_url + "login", form={"token": TOKENS[who], "next": "/whoami"})
    assert r.ok, r.status
    return ctx


def open_page(ctx, gw, path: str):
    page = ctx.new_page()
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(gw.http_url + path)
    if path.startswith("teleop") and "ns=" in path:   # the page has its station (a claim that changes it reloads the page)
        page.wait_for_function("window.teleop?.robotNs?.mine === new URLSearchParams(location.search).get('ns')")
    page.wait_for_function("window.rosgateBooking && !document.querySelector('#booking').hidden")
    return page, errors


def book(gw, who, station, start, end):
    status, body = api(gw, "POST", "/api/bookings", {"station": station, "start": start, "end": end},
                       token=TOKENS[who])
    assert status == 201, body
    return body


def test_time_left_and_the_warnings_at_5_and_1_minutes(chromium, lab):
    now = time.time()
    slot = book(lab, "ada", "/s01", now, now + 290)            # under 5 minutes left from the start
    ctx = signed_in(chromium, lab, "ada")
    try:
        page, errors = open_page(ctx, lab, "teleop?ns=/s01")
        page.wait_for_function("document.querySelector('#booking').textContent.startsWith('Slot /s01')")
        assert "left" in page.inner_text("#booking")
        page.wait_for_function("!document.querySelector('#booking-warning').hidden")
        assert page.get_attribute("#booking-warning", "data-at") == "300"
        assert "5 minutes left" in page.inner_text("#booking-warning")
        page.screenshot(path=str(ARTIFACTS / "booking-teleop-5min.png"))
        # the last minute: another warning
        api(lab, "DELETE", f"/api/bookings/{slot['id']}", token=TOKENS["ada"])
        now = time.time()
        slot = book(lab, "ada", "/s01", now, now + 50)
        page.evaluate("rosgateBooking.refresh()")
        page.wait_for_function("document.querySelector('#booking-warning').dataset.at === '60'")
        assert "1 minute left" in page.inner_text("#booking-warning")
        api(lab, "DELETE", f"/api/bookings/{slot['id']}", token=TOKENS["ada"])
        page.evaluate("rosgateBooking.refresh()")
        page.wait_for_function("document.querySelector('#booking').textContent === 'Booking'")
        assert page.is_hidden("#booking-warning")
        assert not errors, errors
    finally:
        ctx.close()


def test_a_slot_booked_from_the_form_shows_in_the_browsers_time_zone(chromium, lab):
    ctx = signed_in(chromium, lab, "bo", timezone_id=ZONE)
    try:
        page, errors = open_page(ctx, lab, "teleop?ns=/s02")
        page.click("#booking")
        start = datetime.datetime.now(zoneinfo.ZoneInfo(ZONE)).replace(microsecond=0) + datetime.timedelta(hours=2)
        page.select_option("#booking-station", "/s02")
        page.fill("#booking-start", start.strftime("%Y-%m-%dT%H:%M:%S"))
        page.fill("#booking-minutes", "5")
        page.click("#booking-book")
        page.wait_for_function("document.querySelector('#booking-msg').textContent")
        assert page.inner_text('#booking-msg').startswith('Booked'), page.inner_text('#booking-msg')
        mine = [b for b in api(lab, "GET", "/api/bookings?station=/s02", token=TOKENS["bo"])[1]["bookings"] if b["mine"]]
        assert [(b["start"], b["end"] - b["start"]) for b in mine] == [(start.timestamp(), 300)]
        # the table is drawn again after the answer
        page.wait_for_function("t => document.querySelector('#booking-table').innerText.includes(t)", arg=start.strftime("%H:%M:%S"))
        shown = page.inner_text("#booking-table")
        assert start.strftime("%H:%M:%S") in shown and "bo" in shown        # Tokyo's clock, not the machine's
        assert ZONE in page.inner_text("#dlg-booking")
        assert "/s02: free until" in shown
        assert f"/s02 free until {start.strftime('%H:%M:%S')}" in page.inner_text("#booking")   # the walk-in's until
        page.screenshot(path=str(ARTIFACTS / "booking-dialog.png"))
        # an overlapping slot is refused with the gateway's reason
        page.fill("#booking-start", (start + datetime.timedelta(minutes=1)).strftime("%Y-%m-%dT%H:%M:%S"))
        page.click("#booking-book")
        page.wait_for_function("document.querySelector('#booking-msg').classList.contains('error')")
        assert "booked by bo" in page.inner_text("#booking-msg")
        assert not errors, errors
    finally:
        ctx.close()


def test_the_teacher_sees_and_edits_every_stations_timetable(chromium, lab):
    t = time.time() + 7200
    theirs = book(lab, "cy", "/s01", t, t + 60)
    ctx = signed_in(chromium, lab, "teacher")
    try:
        page, errors = open_page(ctx, lab, "class")
        page.click("#booking")
        page.wait_for_selector("#booking-table section[data-station='/s01'] li")
        assert page.locator("#booking-table section").count() == 2      # both stations
        row = page.locator(f"#booking-table li[data-id='{theirs['id']}']")
        assert "cy" in row.inner_text()
        row.locator("button.booking-cancel").click()
        page.wait_for_function("document.querySelector('#booking-msg').textContent.startsWith('Cancelled')")
        assert api(lab, "GET", f"/api/bookings/{theirs['id']}", token=TOKENS["teacher"])[0] == 404
        # and books a slot for a student, who finds it among hers
        start = datetime.datetime.fromtimestamp(t + 600).replace(microsecond=0)
        page.select_option("#booking-station", "/s02")
        page.fill("#booking-start", start.strftime("%Y-%m-%dT%H:%M:%S"))
        page.fill("#booking-minutes", "2")
        page.fill("#booking-for", "cy")
        page.click("#booking-book")
        page.wait_for_function("document.querySelector('#booking-msg').textContent.endsWith('for cy.')")
        hers = [b for b in api(lab, "GET", "/api/bookings?station=/s02", token=TOKENS["cy"])[1]["bookings"] if b["mine"]]
        assert [(b["start"], b["name"]) for b in hers] == [(start.timestamp(), "cy")]
        api(lab, "DELETE", f"/api/bookings/{hers[0]['id']}", token=TOKENS["cy"])
        assert not errors, errors
    finally:
        ctx.close()


def test_teleop_with_no_free_station_says_no_robot_for_you(chromium, lab):
    held = []
    try:
        for who in ("teacher", "bo"):   # ada may not walk back into /s01 yet: her slot there ended
            ros = roslibpy.Ros(f"ws://{lab.host}:{lab.port}/?token={TOKENS[who]}")
            ros.run(timeout=10)
            held.append(ros)
            answer = roslibpy.Service(ros, "/fleet/claim", "std_srvs/srv/Trigger").call(roslibpy.ServiceRequest({}), timeout=10)
            assert answer["success"], answer
        ctx = signed_in(chromium, lab, "cy")
        try:
            page = ctx.new_page()
            page.goto(lab.http_url + "teleop")
            page.wait_for_function("document.body?.dataset.connection === 'connected'")
            page.wait_for_function("(window.teleop?.blocked || '').startsWith('No robot for you')")
            assert page.inner_text("#notice").startswith("No robot for you: all 2 stations are taken")
            assert "Claiming" not in page.inner_text("#notice")
            # she queues from the booking panel, and is seated when the teacher frees /s02
            page.wait_for_function("window.rosgateBooking && !document.querySelector('#booking').hidden")
            page.click("#booking")
            page.click("#booking-queue")
            page.wait_for_function("document.querySelector('#booking-queue-text').textContent.startsWith('You are number 1 of 1')")
            assert "estimated wait unknown" in page.inner_text("#booking-queue-text")   # walk-ins have no known end
            page.screenshot(path=str(ARTIFACTS / "booking-queue.png"))
            released = roslibpy.Service(held[0], "/s02/fleet/release", "std_srvs/srv/Trigger").call(
                roslibpy.ServiceRequest({}), timeout=10)
            assert released["success"], released
            page.wait_for_url(re.compile(r"ns=/s02"))
            page.wait_for_load_state()
            page.wait_for_function("window.teleop?.robotNs?.mine === '/s02'")
        finally:
            ctx.close()
    finally:
        for ros in held:
            ros.close()


def test_the_ide_shows_the_time_left_too(chromium, lab):
    now = time.time()
    slot = book(lab, "cy", "/s02", now, now + 100)
    ctx = signed_in(chromium, lab, "cy")
    try:
        page, errors = open_page(ctx, lab, "?ns=/s02")
        page.wait_for_function("document.querySelector('#booking').textContent.startsWith('Slot /s02 · 1:')")
        assert page.get_attribute("#booking-warning", "data-at") == "300"
        page.screenshot(path=str(ARTIFACTS / "booking-ide.png"))
        assert not errors, errors
    finally:
        ctx.close()
        api(lab, "DELETE", f"/api/bookings/{slot['id']}", token=TOKENS["cy"])
