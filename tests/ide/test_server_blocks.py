"""The "every N s" block and the server blocks ("when service S is called, answer", "serve action A: feedback, result"): the
program Run in the page (JavaScript) and its Python script (roslibpy) answer a roslibpy service call
and an action goal through the gateway."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.support.ros import client
from tests.support.servers import ADD, COUNT, check_served, program

PROGRAM = program()


@pytest.fixture(scope='module')
def gw(start_gateway):
    return start_gateway('--robot', 'turtlesim')


def test_the_page_serves_the_service_and_the_action(gw, ide_factory):
    ide = ide_factory(gw)
    ide.js('(p) => rosgateIde.loadProgram(p)', PROGRAM)
    js = ide.javascript()
    assert f"rt.serveService('{ADD}', 'example_interfaces/srv/AddTwoInts', async (message) => {{" in js
    assert "rt.every(0.1, async () => {" in js
    assert f"rt.serveAction('{COUNT}'" in js and 'rt.actionFeedback(goalHandle, {sequence: [i]});' in js
    ide.run()
    ide.page.wait_for_function("/handlers keep running/.test(document.querySelector('#console-lines').innerText)", timeout=10000)
    with client(gw) as ros:
        check_served(ros)
    ide.page.click('#stop')
    ide.wait_idle()
    assert not ide.errors, ide.errors


def test_the_python_script_serves_them_too(gw, ide_factory, tmp_path):
    ide = ide_factory(gw)
    ide.js('(p) => rosgateIde.loadProgram(p)', PROGRAM)
    script = ide.python()
    assert f"rt.serve_service('{ADD}', 'example_interfaces/srv/AddTwoInts', on_call)" in script
    assert "rt.action_feedback(goal_handle, {'sequence': [i]})" in script and 'rt.every(0.1, every_tick)' in script
    (tmp_path / 'served.py').write_text(script)
    proc = subprocess.Popen([sys.executable, str(tmp_path / 'served.py'), '--url', gw.ws_url],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        with client(gw) as ros:
            check_served(ros)
    finally:
        proc.terminate()
        out, _ = proc.communicate(timeout=20)
    assert 'Traceback' not in out, out
