"""Pages of other origins, in Chromium, against a gateway with and without --auth (--exclusive-control
--fleet 3): a page served from another port of the same host (same site for cookies: the admin's
cookie goes along) or from another host name (localhost against 127.0.0.1) gets no websocket,
takes no driver lease, plays nothing, and its login form does not change who the browser is
signed in as."""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest

from tests.support.auth import TOKENS, tokens_toml
from tests.support.http import api
from tests.support.wait import wait_for
from tests.support.wsclient import Client

ATTACK = """<!doctype html><meta charset="utf-8"><title>elsewhere</title><script>
const gw = %(gw)s, result = window.result = {ws: 'pending', play: 'pending', text: 'pending'};
const ws = new WebSocket(gw.replace('http', 'ws') + '/');
ws.onopen = () => {
  result.ws = 'open';
  ws.send(JSON.stringify({op: 'publish', topic: '/rosgate/control', type: 'std_msgs/msg/String',
                          msg: {data: 'take /s01'}}));
};
ws.onerror = () => { if (result.ws === 'pending') result.ws = 'refused'; };
// a simple request (no preflight): an empty body, and a text/plain one that is JSON inside
fetch(gw + '/api/recordings/%(rec)s/play', {method: 'POST', mode: 'no-cors', credentials: 'include'})
  .then(() => { result.play = 'answered'; }, () => { result.play = 'failed'; });
fetch(gw + '/api/recordings', {method: 'POST', mode: 'no-cors', credentials: 'include',
                               headers: {'Content-Type': 'text/plain'}, body: '{"topics": ["/*"]}'})
  .then(() => { result.text = 'answered'; }, () => { result.text = 'failed'; });
</script>"""

LOGIN_FORM = """<!doctype html><meta charset="utf-8"><title>elsewhere</title>
<form id="f" method="post" action="%(gw)s/login"><input name="token" value="%(token)s">
<input name="next" value="/whoami"></form><script>document.getElementById('f').submit()</script>"""


class Elsewhere:
    """A tiny web server on another port of this host, serving the pages it is given."""

    def __init__(self):
        pages = self.pages = {}

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self):
                body = pages.get(self.path.split('?')[0], '').encode()
                self.send_response(200 if body else 404)
                self.send_header('Content-Type', 'text/html; charset=utf-8')
                self.send_header('Content-Length', str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(('127.0.0.1', 0), Handler)
        self.port = self.server.server_address[1]
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture(scope='module')
def elsewhere():
    site = Elsewhere()
    yield site
    site.close()


@pytest.fixture(scope='module', params=['auth', 'open'])
def school(request, start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('cross-origin')
    flags = ['--robot', 'turtlesim', '--fleet', '3', '--exclusive-control', '--allow-runs',
             '--runs-dir', str(folder / 'runs'), '--record', str(folder / 'rec'),
             '--record-topics', '/s03/turtle1/color_sensor', '--cmd-timeout', '0']
    if request.param == 'auth':
        (folder / 'tokens.toml').write_text(tokens_toml())
        flags += ['--auth', str(folder / 'tokens.toml')]
    gw = start_gateway(*flags)
    gw.auth = request.param == 'auth'
    # a recording of a few seconds to play (the admin's)
    status, body = api(gw, 'POST', '/api/recordings', {'topics': ['/s02/turtle1/pose'], 'max_seconds': 3},
                       TOKENS['admin'])
    assert status == 201, body
    gw.rec = body['id']
    wait_for(lambda: api(gw, 'GET', f'/api/recordings/{gw.rec}', token=TOKENS['admin'])[1]['state'] == 'done', 30)
    yield gw
    gw.stop()


@pytest.fixture
def browser(chromium, school):
    """A browser signed in as the teacher (with --auth) through the gateway's own login page."""
    ctx = chromium.new_context()
    page = ctx.new_page()
    if school.auth:
        page.goto(f'{school.http_url}login?next=/whoami')
        page.fill('input[name=token]', TOKENS['admin'])
        page.click('button[type=submit]')
        page.wait_for_url('**/whoami')
        assert json.loads(page.inner_text('body'))['name'] == 'teacher'
    yield page
    ctx.close()


def signed_in_as(page, gw) -> str | None:
    page.goto(f'{gw.http_url}whoami')
    return json.loads(page.inner_text('body')).get('name')


def driver_of(gw, group: str):
    with Client(gw.ws_url, TOKENS['viewer'] if gw.auth else None) as viewer:
        viewer.subscribe('/rosgate/driver', 'std_msgs/msg/String')
        return json.loads(viewer.next_message('/rosgate/driver')['data'])['drivers'].get(group)


def recording_state(gw) -> tuple[bool, int]:
    recs = api(gw, 'GET', '/api/recordings', token=TOKENS['admin'])[1]['recordings']
    return next(r for r in recs if r['id'] == gw.rec).get('playing', False), len(recs)


@pytest.mark.parametrize('host', ['127.0.0.1', 'localhost'])
def test_a_page_elsewhere_gets_no_websocket_no_lease_and_plays_nothing(school, browser, elsewhere, host):
    before = recording_state(school)
    elsewhere.pages['/attack.html'] = ATTACK % {'gw': json.dumps(school.http_url.rstrip('/')), 'rec': school.rec}
    browser.goto(f'http://{host}:{elsewhere.port}/attack.html')
    browser.wait_for_function("Object.values(window.result).every(v => v !== 'pending')", timeout=15000)
    result = browser.evaluate('window.result')
    assert result['ws'] == 'refused', result        # the websocket never opened
    # the requests reached the gateway (their answers are opaque to the page) and did nothing
    assert result['play'] == 'answered' and result['text'] == 'answered', result
    assert recording_state(school) == before == (False, before[1])
    assert driver_of(school, '/s01') is None
    if school.auth:
        assert signed_in_as(browser, school) == 'teacher'


@pytest.mark.parametrize('host', ['127.0.0.1', 'localhost'])
def test_a_login_form_elsewhere_does_not_sign_the_browser_in(school, browser, elsewhere, host):
    if not school.auth:
        pytest.skip('nobody signs in without --auth')
    elsewhere.pages['/login.html'] = LOGIN_FORM % {'gw': school.http_url.rstrip('/'), 'token': TOKENS['operator2']}
    browser.goto(f'http://{host}:{elsewhere.port}/login.html')
    browser.wait_for_url(lambda url: url.startswith(school.http_url))   # the form went to the gateway
    assert signed_in_as(browser, school) == 'teacher'   # not bob
    # the gateway's own login page still signs in
    browser.goto(f'{school.http_url}login?next=/whoami')
    browser.fill('input[name=token]', TOKENS['operator2'])
    browser.click('button[type=submit]')
    browser.wait_for_url('**/whoami')
    assert signed_in_as(browser, school) == 'bob'
