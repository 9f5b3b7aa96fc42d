"""Launching rosgate from an LMS (LTI 1.3), end to end in Chromium: a platform of its own
(``lti_platform``, on PyJWT) starts each launch with a form post through the browser, the tool's
/lti/login redirects the browser to the platform, the platform posts the signed id_token back;
the gateway runs as a school would run it (``--fleet 3 --auth FILE --lti FILE``).

The platform is at http://127.0.0.1:P and the tool at http://localhost:T: two sites, so the
launch's form post is cross-site as from a real LMS (Chromium counts localhost as secure, so the
Secure state cookie is kept over plain http here, as over https at a school).
"""

from __future__ import annotations

import json
from urllib.parse import urlsplit

import jwt
import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import rsa

from tests.conftest import wait_for
from tests.security.client import Client

from .lti_platform import CLAIM, DL, INST_ADMIN, INSTRUCTOR, LEARNER, STUDENT, Platform

ADMIN_TOKEN = 'lti-test-admin-token-77'


@pytest.fixture(scope='module')
def lab(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('lti')
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    (folder / 'tool.pem').write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                                        serialization.NoEncryption()))
    platform = Platform(tool='http://localhost:0')
    (folder / 'tool.json').write_text(json.dumps(platform.tool_config('tool.pem')))
    (folder / 'tokens.toml').write_text(f'[[tokens]]\nname = "teacher"\nrole = "admin"\ntoken = "{ADMIN_TOKEN}"\n')
    gw = start_gateway('--robot', 'turtlesim', '--fleet', '3', '--auth', str(folder / 'tokens.toml'),
                       '--lti', str(folder / 'tool.json'))
    platform.tool = f'http://localhost:{gw.port}'
    yield gw, platform
    platform.stop()


@pytest.fixture
def browser(chromium):
    contexts = []

    def make():
        ctx = chromium.new_context(viewport={'width': 1180, 'height': 820})
        contexts.append(ctx)
        page = ctx.new_page()
        page.errors = []
        page.on('pageerror', lambda e: page.errors.append(str(e)))
        return page

    yield make
    for ctx in contexts:
        ctx.close()


def whoami(page) -> dict:
    """/whoami as this browser's pages ask it (its cookies, same origin)."""
    return page.evaluate("fetch('/whoami', {credentials: 'same-origin'}).then(async r => "
                         "({status: r.status, body: r.ok ? await r.json() : null}))")


def launch(page, url: str, landing: str):
    page.goto(url)
    page.wait_for_url(f'**{landing}', timeout=20000)
    return urlsplit(page.url)


def teleop_ready(page, ns: str | None = None) -> str:
    page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=20000)
    page.wait_for_function("document.body?.dataset.connection === 'connected'", timeout=10000)
    page.wait_for_function("/^\\/s0[1-3]$/.test(document.querySelector('#ns').value)"
                           + (f" && document.querySelector('#ns').value === '{ns}'" if ns else ''), timeout=10000)
    return page.input_value('#ns')


def refused(page, url: str) -> str:
    page.goto(url)
    page.wait_for_selector('#reason', timeout=20000)
    assert 'This launch was refused' in page.inner_text('h1')
    who = whoami(page)
    assert who['status'] == 401, who           # nobody signed in
    cookies = {c['name'] for c in page.context.cookies()}
    assert 'rosgate_session' not in cookies, cookies
    return page.inner_text('#reason')


def test_a_learner_lands_on_teleop_as_operator_and_drives_a_station(lab, browser):
    gw, platform = lab
    page = browser()
    where = launch(page, platform.add('student-ann', [LEARNER, STUDENT], name='Ann Lee', target='/teleop'),
                   '/teleop')
    assert where.path == '/teleop'
    ns = teleop_ready(page)
    assert whoami(page) == {'status': 200, 'body': {'auth': True, 'name': 'Ann Lee', 'role': 'operator'}}
    cookie = next(c for c in page.context.cookies() if c['name'] == 'rosgate_session')
    assert cookie['httpOnly'] and cookie['sameSite'] == 'Lax'
    assert 'student-ann' not in cookie['value']
    # the page drives its station: its commands reach the station's turtle (watched by the teacher)
    with Client(gw.ws_url, ADMIN_TOKEN) as watcher:
        watcher.subscribe(f'{ns}/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
        page.locator('body').click(position={'x': 5, 'y': 5})
        page.keyboard.down('ArrowUp')
        msg = watcher.expect(lambda m: m.get('op') == 'publish' and m['msg']['linear']['x'] > 0, timeout=10)
        page.keyboard.up('ArrowUp')
        assert msg['topic'] == f'{ns}/turtle1/cmd_vel'
    assert not page.errors, page.errors


def test_an_instructor_lands_on_the_class_view_as_admin(lab, browser):
    gw, platform = lab
    page = browser()
    launch(page, platform.add('prof-bo', [INSTRUCTOR, STUDENT], name='Bo Chen', target='/class'), '/class')
    assert whoami(page)['body'] == {'auth': True, 'name': 'Bo Chen', 'role': 'admin'}
    page.wait_for_function("document.body?.dataset.connection === 'connected'", timeout=20000)
    # institution roles do not make a Learner an admin: membership roles decide
    other = browser()
    launch(other, platform.add('student-cy', [LEARNER, INST_ADMIN], target='/class'), '/class')
    assert whoami(other)['body']['role'] == 'operator'
    assert '403' in other.inner_text('body')


def test_custom_page_and_station_are_honoured(lab, browser):
    gw, platform = lab
    page = browser()
    where = launch(page, platform.add('student-dee', [LEARNER], target='/', custom={'page': 'teleop', 'station': 's03'}),
                   '/teleop?ns=/s03')
    assert where.path == '/teleop'
    assert teleop_ready(page, '/s03') == '/s03'
    # the IDE with an example program (as the deep linking picker stores it)
    ide = browser()
    launch(ide, platform.add('student-dee', [LEARNER], target='/', custom={'program': 'example:spiral'}),
           '/?program=example:spiral')
    ide.wait_for_function("document.body?.dataset.ready === 'true'", timeout=20000)
    assert ide.evaluate('rosgateIde.programName') == 'spiral with the pen'
    ide.wait_for_function("document.body?.dataset.connection === 'connected'", timeout=10000)


def test_two_learners_get_two_stations_and_a_relaunch_the_same(lab, browser):
    gw, platform = lab
    with Client(gw.ws_url, ADMIN_TOKEN) as teacher:     # earlier tests' students keep theirs otherwise
        assert teacher.call('/fleet/release_all', {})['result'] is True
    first, second = browser(), browser()
    launch(first, platform.add('student-eve', [LEARNER], target='/teleop'), '/teleop')
    a = teleop_ready(first)
    launch(second, platform.add('student-finn', [LEARNER], target='/teleop'), '/teleop')
    b = teleop_ready(second)
    assert a != b
    again = browser()                      # Eve again, from another browser: her station
    launch(again, platform.add('student-eve', [LEARNER], target='/teleop'), '/teleop')
    assert teleop_ready(again) == a


def test_forged_launches_are_refused_and_nobody_is_signed_in(lab, browser):
    gw, platform = lab
    cases = {
        'key': 'signature does not match',
        'aud': 'another tool',
        'expired': 'expired',
        'deployment': 'deployment',
        'state': 'state',
    }
    for forge, words in cases.items():
        reason = refused(browser(), platform.add(f'mallory-{forge}', [INSTRUCTOR], target='/class', forge=forge))
        assert words in reason, (forge, reason)

    # the state is bound to the browser that began the sign-in: a launch begun in one browser and
    # posted from another (its form taken on the way) signs nobody in
    victim = browser()
    victim.route('**/lti/launch', lambda route: route.abort())
    before = len(platform.posted)
    victim.goto(platform.add('student-hana', [INSTRUCTOR], target='/class'))
    wait_for(lambda: len(platform.posted) > before, timeout=20)
    reason = refused(browser(), f'{platform.issuer}/post?i={before}')
    assert 'state mismatch' in reason, reason

    # a replayed id_token: the same post again, and the same token with a new login's state
    page = browser()
    launch(page, platform.add('student-gus', [LEARNER], target='/teleop'), '/teleop')
    index = len(platform.posted) - 1
    thief = browser()
    reason = refused(thief, f'{platform.issuer}/post?i={index}')
    assert 'already used' in reason or 'state' in reason, reason
    reason = refused(browser(), platform.add('student-gus', [LEARNER], target='/teleop', forge=f'replay:{index}'))
    assert 'nonce' in reason, reason


def test_deep_linking_round_trip(lab, browser):
    gw, platform = lab
    page = browser()
    page.goto(platform.add('prof-hal', [INSTRUCTOR], kind='LtiDeepLinkingRequest', target='/'))
    page.wait_for_selector('#add', timeout=20000)
    page.check("input[value='teleop']")
    page.fill("input[name=station]", 's02')
    page.fill("input[name=title]", 'Drive the robot')
    page.click('#add')
    page.wait_for_selector('#done', timeout=20000)
    assert len(platform.returned) == 1
    token = platform.returned[0]
    keys = jwt.PyJWKClient(f'{platform.tool}/lti/jwks')
    claims = jwt.decode(token, keys.get_signing_key_from_jwt(token).key, algorithms=['RS256'],
                        audience=platform.issuer, issuer=platform.client_id)
    assert claims[CLAIM + 'message_type'] == 'LtiDeepLinkingResponse'
    assert claims[CLAIM + 'version'] == '1.3.0' and claims[CLAIM + 'deployment_id'] == platform.deployment
    assert claims[DL + 'data'] == 'opaque-42'
    item, = claims[DL + 'content_items']
    assert item == {'type': 'ltiResourceLink', 'title': 'Drive the robot', 'url': f'{platform.tool}/teleop',
                    'custom': {'station': 's02'}}
    # a student may not add activities
    reason = refused(browser(), platform.add('student-ivy', [LEARNER], kind='LtiDeepLinkingRequest'))
    assert 'teachers' in reason


def test_config_page_and_jwks(lab, browser):
    gw, platform = lab
    page = browser()
    page.goto(f'{platform.tool}/lti/config')
    text = page.inner_text('body')
    for words in ('Initiate login URL', 'Redirection URI(s)', 'OpenID Connect Initiation Url', 'Public JWK URL',
                  f'{platform.tool}/lti/login', f'{platform.tool}/lti/launch', f'{platform.tool}/lti/jwks',
                  platform.issuer, 'https://canvas.example.edu'):
        assert words in text, words
    keys = page.evaluate("fetch('/lti/jwks').then(r => r.json())")['keys']
    assert keys and all(k['kty'] == 'RSA' and k['alg'] == 'RS256' and 'd' not in k for k in keys)
