"""The IDE on a gateway with --auth, in Chromium: signed out it says so and links to /login (no
green "connected"); signed in it asks /whoami and offers what the role may use (a viewer
neither runs nor saves); each student saves into a library space of their own, and the
teacher (admin) sees everyone's programs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.support.ide import TABLET, IdePage, ex, program

TOKENS = {"viewer": "ide-viewer-token-11", "operator": "ide-operator-token-22", "admin": "ide-admin-token-33"}
NAMES = {"viewer": "vera", "operator": "alice", "admin": "teacher"}


@pytest.fixture(scope="module")
def auth_gateway(start_gateway, tmp_path_factory):
    path = tmp_path_factory.mktemp("ide-auth") / "tokens.toml"
    path.write_text("".join(f'[[tokens]]\nname = "{NAMES[r]}"\nrole = "{r}"\ntoken = "{t}"\n\n'
                            for r, t in TOKENS.items()))
    return start_gateway("--robot", "turtlesim", "--auth", str(path), "--allow-runs")


@pytest.fixture
def browser_page(chromium):
    contexts = []

    def make(gateway) -> IdePage:
        ctx = chromium.new_context(viewport=TABLET, has_touch=True)
        contexts.append(ctx)
        return IdePage(ctx.new_page(), gateway)

    yield make
    for ctx in contexts:
        ctx.close()


def open_signed_out(ide: IdePage):
    ide.page.goto(ide.gateway.http_url)
    ide.page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=20000)


def sign_in(ide: IdePage, role: str):
    """Through the page: the Sign in link, the login form, back to the IDE."""
    open_signed_out(ide)
    ide.errors.clear()          # the signed-out page's requests were answered 401, as they should
    ide.page.click("#signin")
    ide.page.wait_for_url("**/login?next=*")
    ide.page.fill("input[name=token]", TOKENS[role])
    ide.page.click("button[type=submit]")
    ide.page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=20000)
    ide.page.wait_for_function("document.body?.dataset.connection === 'connected'", timeout=10000)


def test_signed_out_links_to_login(auth_gateway, browser_page):
    ide = browser_page(auth_gateway)
    open_signed_out(ide)
    assert ide.js("document.querySelector('#status').dataset.state") == "signin"
    assert ide.page.inner_text("#status") == "not signed in"
    assert ide.js("document.body.dataset.connection") != "connected"
    assert ide.page.is_visible("#signin")
    assert ide.js("document.querySelector('#signin').getAttribute('href')") == "login?next=%2F"
    assert ide.page.is_disabled("#run") and ide.page.is_disabled("#step")
    assert "sign in" in ide.console_text().lower()
    ide.screenshot("ide-auth-signed-out")
    # no websocket was opened: nothing to refuse
    assert not any(u.startswith("ws") for u in ide.requests)


def test_viewer_may_watch_but_not_run_or_save(auth_gateway, browser_page):
    ide = browser_page(auth_gateway)
    sign_in(ide, "viewer")
    assert ide.js("rosgateIde.me") == {"auth": True, "signedIn": True, "name": "vera", "role": "viewer"}
    assert ide.page.inner_text("#who-name") == "vera" and not ide.page.is_visible("#signin")
    assert ide.page.is_disabled("#run") and ide.page.is_disabled("#step") and ide.page.is_disabled("#pause")
    ide.page.wait_for_function("document.body?.dataset.robotRuns === 'allowed'", timeout=10000)
    assert ide.page.is_visible("#run-robot") and ide.page.is_disabled("#run-robot")
    ide.page.click("#library")
    ide.page.wait_for_selector("#library-space:not([hidden])")
    assert ide.page.is_disabled("#library-save")
    assert "vera" in ide.page.inner_text("#library-space")
    assert not ide.errors, ide.errors


def test_students_save_in_their_own_space_and_the_teacher_sees_all(auth_gateway, browser_page):
    student = browser_page(auth_gateway)
    sign_in(student, "operator")
    assert student.page.inner_text("#who-role") == "(operator)"
    assert not student.page.is_disabled("#run")
    student.page.wait_for_function("document.body?.dataset.robotRuns === 'allowed'", timeout=10000)
    assert not student.page.is_disabled("#run-robot")
    student.js("(p) => rosgateIde.loadProgram(p)", program(ex.log(ex.text("alice was here")), name="alice square"))
    student.run()
    student.wait_idle(timeout=15)
    assert student.logs() == ["alice was here"]
    student.page.click("#library")
    student.page.click("#library-save")
    student.page.wait_for_selector("#library-list .lib-open")
    assert "saved" in student.console_text() and "failed" not in student.console_text()
    stored = Path(auth_gateway.programs_dir) / "users" / "alice" / "alice square.json"
    assert json.loads(stored.read_text())["name"] == "alice square"
    assert student.page.inner_text("#library-list .lib-open") == "alice square"
    student.screenshot("ide-auth-student-library")

    teacher = browser_page(auth_gateway)
    sign_in(teacher, "admin")
    teacher.page.click("#library")
    item = teacher.page.locator("#library-list .lib-open", has_text="alice / alice square")
    item.wait_for()
    teacher.screenshot("ide-auth-teacher-library")
    item.click()
    teacher.page.wait_for_function("rosgateIde.programName === 'alice square'")
    assert "rt.log('alice was here');" in teacher.javascript()
    assert not student.errors and not teacher.errors, (student.errors, teacher.errors)
