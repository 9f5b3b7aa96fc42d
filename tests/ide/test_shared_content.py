"""What comes from outside the IDE is data (issue 46), in Chromium and Firefox ESR, the teacher signed
in as a student's link would find her: a share link's block with a ``javascript:`` Help address is
refused (it ran in the gateway's origin and published itself to the class's library); a text program
from another person's link runs only once she says so, seeing whose it is, and then without her
admin rights: apart from the page (no fetch of the gateway's API) and as an operator on the
websocket (no teacher's stop). The gateway's own check of the class's library is in
tests/security/test_class_doors.py."""

from __future__ import annotations

import base64
import json
import zlib

import pytest
import roslibpy

from tests.support import engines
from tests.support.auth import TOKENS, tokens_toml
from tests.support.http import api, http
from tests.support.wait import wait_for

TEACHER, BOB = TOKENS['admin'], TOKENS['operator2']
READY = "document.body?.dataset.ready === 'true' && document.body.dataset.connection === 'connected'"
MADE_EVIL = {
    'json': {'type': 'my_evil', 'message0': 'help me', 'previousStatement': None, 'nextStatement': None,
             'tooltip': 'a harmless block',
             'helpUrl': "javascript:fetch('api/blocks/shared',{method:'POST',headers:{'Content-Type':"
                        "'application/json'},body:JSON.stringify({json:{type:'my_worm',message0:'worm'},"
                        "spec:{kind:'publish'}})}).then(()=>window.__ran=1)"},
    'spec': {'kind': 'publish', 'topic': '/chatter', 'type': 'std_msgs/msg/String', 'msg': {'data': 'x'}},
    'toolboxInputs': {}}
WORM = {'json': {'type': 'my_worm', 'message0': 'worm'}, 'spec': {'kind': 'publish', 'topic': '/chatter',
                                                                   'type': 'std_msgs/msg/String', 'msg': {}}}
TEXT_PROGRAM = """import { rt } from 'rosgate';
const control = new ROSLIB.Topic({ ros, name: '/rosgate/control', messageType: 'std_msgs/msg/String' });
control.publish({ data: 'stop /s01' });
await rt.sleep(1);
try { await import('/api/exercise-results', { with: { type: 'json' } }); console.log('read the API'); } catch (e) { console.log('no API'); }
console.log('fetch is ' + typeof fetch);
const res = await fetch('api/blocks/shared', { method: 'POST', headers: { 'Content-Type': 'application/json' },
  body: JSON.stringify(%s) });
console.log('published ' + res.status);
""" % json.dumps(WORM)


@pytest.fixture(scope='module')
def school(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('shared-content')
    (folder / 'tokens.toml').write_text(tokens_toml())
    (folder / 'blocks').mkdir()
    return start_gateway('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--auth',
                         str(folder / 'tokens.toml'), '--blocks-dir', str(folder / 'blocks'), '--cmd-timeout', '0')


@pytest.fixture(scope='module', params=['chromium', 'firefox'])
def engine(request):
    if request.param == 'chromium':
        e = engines.Chromium(request.getfixturevalue('chromium'))
    else:
        try:
            e = engines.Firefox()
        except RuntimeError as err:
            pytest.fail(str(err))
    yield e
    e.close()
    if request.param == 'firefox':
        e.quit()


def link(gw, program: dict, token: str | None = None) -> str:
    """A share link as the IDE writes one (storage.shareLink): the program, signed by ``token``'s person."""
    text = json.dumps(program, separators=(',', ':'), ensure_ascii=False)
    payload = program
    if token is not None:
        reply = http(gw, '/api/share', method='POST', json={'text': text}, token=token)
        shared = reply.json() if reply.status == 200 else {}
        payload = {**program, 'shared': shared} if shared.get('sig') else program
    packer = zlib.compressobj(9, zlib.DEFLATED, -15)
    packed = packer.compress(json.dumps(payload, separators=(',', ':'), ensure_ascii=False).encode()) + packer.flush()
    return gw.http_url + '?from=link#program=' + base64.urlsafe_b64encode(packed).decode().rstrip('=')


def signed_in(engine, gw, token: str, url: str) -> None:
    """Signed in through /login (the session cookie), then the link opened in that browser."""
    engine.open(gw.http_url + 'login?next=/')
    engine.fill('input[name=token]', token)
    engine.click('button[type=submit]')
    engine.wait("location.pathname === '/' && document.body?.dataset.ready === 'true'", 60, 'signed in')
    if isinstance(engine, engines.Chromium):
        engine.page.goto(url)        # the same browser context: its cookie
    else:
        engine.open(url)             # a new tab of the same profile
    engine.wait(READY, 60, 'the IDE ready and connected')


def console_text(engine) -> str:
    return engine.js("document.querySelector('#console-lines').innerText")


def shared_library(gw) -> list[str]:
    return [m['json']['type'] for m in api(gw, 'GET', '/api/blocks', token=TEACHER)[1]['shared']]


def test_a_links_block_with_a_javascript_help_address_is_refused(engine, school):
    program = {'format': 'rosgate-program', 'version': 1, 'name': 'help me', 'robot': 'any', 'blocks': [MADE_EVIL],
               'workspace': {'blocks': {'languageVersion': 0, 'blocks': [{'type': 'my_evil', 'x': 20, 'y': 20}]}}}
    signed_in(engine, school, TEACHER, link(school, program, BOB))
    engine.wait("document.querySelector('#console-lines').innerText.includes('helpUrl')", 30, 'the refusal said')
    assert engine.js("!Blockly.Blocks.my_evil && !rosgateIde.workspace.getAllBlocks(false).length")
    # nothing took its place either: a block of the IDE's own with such a Help does nothing
    engine.js("(() => { const b = rosgateIde.workspace.newBlock('controls_if'); b.helpUrl = 'javascript:window.__ran=1'; "
              "b.showHelp(); })()")
    assert engine.js('!window.__ran')
    assert 'my_worm' not in shared_library(school) and 'my_evil' not in shared_library(school)


def watch_driver(gw):
    ros = roslibpy.Ros(f"ws://{gw.host}:{gw.port}/?token={TOKENS['viewer']}")
    ros.run(timeout=30)
    seen: list = []
    topic = roslibpy.Topic(ros, '/rosgate/driver', 'std_msgs/msg/String')
    topic.subscribe(lambda m: seen.append(json.loads(m['data'])))
    wait_for(lambda: seen, 30, what='the driver state')
    return ros, seen


def text_program(text: str) -> dict:
    return {'format': 'rosgate-program', 'version': 1, 'kind': 'text', 'lang': 'javascript', 'name': 'from bob',
            'robot': 'any', 'text': text}


def test_another_persons_text_program_asks_first_and_runs_without_the_teachers_rights(engine, school):
    ros, driver = watch_driver(school)
    try:
        signed_in(engine, school, TEACHER, link(school, text_program(TEXT_PROGRAM), BOB))
        engine.wait("!!document.querySelector('.cm-content')", 60, 'the text program open')
        engine.wait("!!rosgateIde.ns", 60, 'a station claimed')     # a Run before it says "No robot yet"
        # Cancel: it does not run
        engine.click('#run')
        engine.wait("document.querySelector('#dlg-foreign').open", 20, 'the question')
        assert 'bob' in engine.js("document.querySelector('#foreign-whose').textContent")
        engine.click('#foreign-cancel')
        engine.wait("!document.querySelector('#dlg-foreign').open && document.body.dataset.run === 'idle'", 20)
        # Run it: apart from the page, as an operator
        engine.click('#run')
        engine.wait("document.querySelector('#dlg-foreign').open", 20, 'the question again')
        engine.click('#foreign-run')
        engine.wait("document.querySelector('#console-lines').innerText.includes('fetch is undefined')", 60,
                    'the program ran, without fetch')
        engine.wait("document.body.dataset.run === 'idle'", 60, 'the program ended')
        text = console_text(engine)
        assert 'published' not in text and 'read the API' not in text and 'no API' in text, text
        assert 'my_worm' not in shared_library(school)
        assert not any('/s01' in d.get('halted', {}) for d in driver), driver    # the teacher's stop was not lent
        assert engine.js("rosgateIde.lowered === true")
    finally:
        ros.close()


def test_ones_own_link_runs_at_once(engine, school):
    program = text_program("console.log('mine ' + (typeof fetch))")
    signed_in(engine, school, BOB, link(school, program, BOB))
    engine.wait("!!document.querySelector('.cm-content')", 60, 'the text program open')
    engine.wait("!!rosgateIde.ns", 60, 'her station claimed')     # a Run before it says "No robot yet"
    engine.click('#run')
    try:
        engine.wait("document.querySelector('#console-lines').innerText.includes('mine function')", 60, 'it ran in the page')
    except AssertionError as e:
        raise AssertionError(f'{e}: {console_text(engine)}') from None
    assert not engine.js("document.querySelector('#dlg-foreign').open")


PYTHON_PROGRAM = """from pyodide.http import open_url
try:
    print('read ' + open_url('/api/exercise-results').read()[:20])
except Exception as e:
    print('no API: ' + type(e).__name__)
print('the end')
"""


def test_another_persons_python_program_reaches_no_api(engine, school):
    program = {**text_program(PYTHON_PROGRAM), 'lang': 'python'}
    signed_in(engine, school, TEACHER, link(school, program, BOB))
    engine.wait("!!document.querySelector('.cm-content')", 60, 'the text program open')
    engine.wait("!!rosgateIde.ns", 60, 'a station claimed')     # a Run before it says "No robot yet"
    engine.click('#run')
    engine.wait("document.querySelector('#dlg-foreign').open", 20, 'the question')
    engine.click('#foreign-run')
    try:   # under pytest-timeout's 180 s, so that a failure shows the console
        engine.wait("document.querySelector('#console-lines').innerText.includes('the end')", 150, 'the program ran')
    except AssertionError as e:
        raise AssertionError(f"{e}: {console_text(engine)}; link lost: {engine.js('rosgateIde.link?.lastLost ?? null')}") from None
    text = console_text(engine)
    assert 'no API' in text and 'read ' not in text, text
