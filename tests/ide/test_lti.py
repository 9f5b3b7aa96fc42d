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
from playwright.sync_api import Error as PlaywrightError

from tests.support.http import api, http
from tests.support.ide import drives_its_station, teleop_ready
from tests.support.wait import wait_for
from tests.support.wsclient import Client

from tests.support.lti_platform import CLAIM, DL, INST_ADMIN, INSTRUCTOR, LEARNER, STUDENT, Platform, write_tool_key

ADMIN_TOKEN = 'lti-test-admin-token-77'


@pytest.fixture(scope='module')
def lab(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('lti')
    write_tool_key(folder / 'tool.pem')
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
        page.console = []       # its warnings and errors, to say why when a test fails
        page.on('console', lambda m: m.type in ('warning', 'error') and page.console.append(m.text))
        return page

    yield make
    for ctx in contexts:
        ctx.close()


def whoami(page) -> dict:
    """/whoami as this browser's pages ask it (its cookies, same origin); asked again in the page
    it became if it reloaded meanwhile (the teleop page reloads into the station it claims)."""
    for _ in range(5):
        try:
            return page.evaluate("fetch('/whoami', {credentials: 'same-origin'}).then(async r => "
                                 "({status: r.status, body: r.ok ? await r.json() : null}))")
        except PlaywrightError as e:
            if 'context was destroyed' not in str(e):
                raise
            page.wait_for_load_state()
    raise AssertionError('the page kept navigating')


def launch(page, url: str, landing: str):
    page.goto(url)
    try:
        page.wait_for_url(f'**{landing}', timeout=20000)
    except Exception:
        raise AssertionError(f'no {landing}: at {page.url}: {page.inner_text("body")[:300]}') from None
    return urlsplit(page.url)


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
    drives_its_station(page, gw, ADMIN_TOKEN, ns)
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
    # a text exercise: the example written as Python text (the picker's "program as")
    text = browser()
    launch(text, platform.add('student-dee', [LEARNER], target='/',
                              custom={'program': 'example:spiral', 'mode': 'text', 'lang': 'python'}),
           '/?program=example:spiral&mode=text&lang=python')
    text.wait_for_function("document.body?.dataset.ready === 'true'", timeout=20000)
    text.wait_for_selector('.cm-content')
    assert text.evaluate('rosgateIde.textMode.lang') == 'python'
    assert 'from rosgate_runtime import *' in text.evaluate('rosgateIde.textMode.text')


def test_the_course_language_comes_with_the_launch(lab, browser):
    gw, platform = lab
    page = browser()
    where = launch(page, platform.add('student-ivo', [LEARNER], target='/teleop', locale='es-ES'), '/teleop?lang=es-ES')
    assert where.path == '/teleop'
    teleop_ready(page)
    assert page.evaluate('document.documentElement.lang') == 'es', (page.url, page.errors, page.console)
    assert page.inner_text('#status') == 'conectado'
    assert page.evaluate("document.querySelector('#claim').textContent") == 'Pedir un robot'
    # the tab's other pages keep the course's language
    page.goto(f'http://localhost:{gw.port}/')
    page.wait_for_function("document.body?.dataset.ready === 'true'", timeout=20000)
    assert page.inner_text('#run') == '▶ Ejecutar'
    # a locale that is no language tag is left out of the landing
    other = browser()
    launch(other, platform.add('student-hal', [LEARNER], target='/teleop', locale='"><script>'), '/teleop')
    assert 'lang=' not in other.url
    assert not page.errors, page.errors


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
        'type': 'message type',
        'version': 'version',
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


def test_a_platform_rotating_its_key_is_followed(lab, browser):
    """The tool keeps the platform's JWKS; a launch signed with a key id it has not seen makes it
    fetch the JWKS again (and then the launch passes)."""
    gw, platform = lab
    first = browser()
    launch(first, platform.add('student-lu', [LEARNER], target='/'), '/')     # the JWKS is cached
    platform.rotate()
    again = browser()
    launch(again, platform.add('student-lu', [LEARNER], target='/'), '/')
    assert whoami(again)['body']['role'] == 'operator'


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
    # a text exercise: the IDE with a new JavaScript program
    page = browser()
    page.goto(platform.add('prof-hal', [INSTRUCTOR], kind='LtiDeepLinkingRequest', target='/'))
    page.wait_for_selector('#add', timeout=20000)
    page.check("input[value='ide']")
    page.select_option("select[name=as]", 'javascript')
    page.click('#add')
    page.wait_for_selector('#done', timeout=20000)
    token = platform.returned[1]
    item, = jwt.decode(token, keys.get_signing_key_from_jwt(token).key, algorithms=['RS256'], audience=platform.issuer,
                       issuer=platform.client_id)[DL + 'content_items']
    assert item['url'] == f'{platform.tool}/' and item['custom'] == {'mode': 'text', 'lang': 'javascript'}
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


@pytest.mark.parametrize('phaseout', [False, True])
def test_a_launch_inside_the_course_page_iframe(lab, chromium, phaseout):
    """In the LMS's iframe the state and session cookies are partitioned (CHIPS); with Chromium's
    third-party cookie phase-out on (unpartitioned cookies blocked in frames), the launch still
    signs the frame in and its page connects."""
    gw, platform = lab
    from tests.support.ide import CHROMIUM, CHROMIUM_ARGS
    browser = chromium.browser_type.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS + [
        '--test-third-party-cookie-phaseout']) if phaseout else chromium
    ctx = browser.new_context(viewport={'width': 1180, 'height': 900})
    try:
        page = ctx.new_page()
        with Client(gw.ws_url, ADMIN_TOKEN) as teacher:
            assert teacher.call('/fleet/release_all', {})['result'] is True
        url = platform.add('student-jo', [LEARNER], target='/teleop').replace('/start?', '/course?')
        page.goto(url)
        try:
            # (page.title() lets Playwright take in the frames' navigations while this waits)
            wait_for(lambda: page.title() and any(f.url.startswith(f'{platform.tool}/teleop') for f in page.frames),
                     timeout=30)
        except AssertionError:
            raise AssertionError([(f.url, f.content()[:600]) for f in page.frames]) from None
        frame = next(f for f in page.frames if f.url.startswith(f'{platform.tool}/teleop'))
        teleop_ready(frame)          # (its station claimed, the page reloads once: wait for that)

        def me():
            try:
                return whoami(frame)
            except Exception:    # the reload of the station's page
                return None
        assert wait_for(me, timeout=20)['body']['name'] == 'student-jo'
        session = [c for c in ctx.cookies() if c['name'] == 'rosgate_session']
        assert session and all(c['sameSite'] == 'None' and c['secure'] for c in session), session
    finally:
        ctx.close()
        if phaseout:
            browser.close()


def test_a_frame_that_keeps_no_cookies_continues_in_a_new_window(lab, browser):
    """As Safari in an LMS's iframe: the launch's session cookie is dropped (the route below takes
    it out of the answer); the page offers "Continue in a new window", which signs that window in
    once (the link's ticket is single-use)."""
    gw, platform = lab
    page = browser()

    def drop_session_cookie(route):
        response = route.fetch()
        headers = {k: v for k, v in response.headers.items() if k.lower() != 'set-cookie'}
        route.fulfill(response=response, headers=headers)

    page.route('**/lti/launch', drop_session_cookie)
    page.goto(platform.add('student-kim', [LEARNER], target='/teleop').replace('/start?', '/course?'))
    wait_for(lambda: page.title() and any(f.url.endswith('/lti/launch') for f in page.frames), timeout=30)
    frame = next(f for f in page.frames if f.url.endswith('/lti/launch'))
    frame.wait_for_selector('#newwin', state='visible', timeout=20000)
    with page.context.expect_page() as opened:
        frame.click('#newwin')
    window = opened.value
    window.wait_for_url('**/teleop**', timeout=20000)
    teleop_ready(window)
    assert whoami(window)['body']['name'] == 'student-kim'
    ticket_url = frame.get_attribute('#newwin', 'href')
    again = browser()
    again.goto(f'{platform.tool}{ticket_url}')
    assert 'used or more than' in again.inner_text('#reason')


def test_the_teacher_books_a_slot_for_a_student_from_the_lms(start_gateway, browser, tmp_path):
    """A student known only by her LMS launch (her key is a digest of issuer and subject) gets a
    slot the teacher books "for" her by name: it is hers on her pages, and she drives in it."""
    import time
    write_tool_key(tmp_path / 'tool.pem')
    platform = Platform(tool='http://localhost:0')
    try:
        (tmp_path / 'tool.json').write_text(json.dumps(platform.tool_config('tool.pem')))
        (tmp_path / 'tokens.toml').write_text(f'[[tokens]]\nname = "teacher"\nrole = "admin"\ntoken = "{ADMIN_TOKEN}"\n')
        gw = start_gateway('--robot', 'turtlesim', '--fleet', '2', '--auth', str(tmp_path / 'tokens.toml'),
                           '--lti', str(tmp_path / 'tool.json'), '--booking')
        platform.tool = f'http://localhost:{gw.port}'

        twins = []
        for sub in ('student-gil', 'student-gil-2'):        # two Gil Rays in the course, and Hana
            page = browser()
            launch(page, platform.add(sub, [LEARNER], name='Gil Ray', target='/teleop'), '/teleop')
            twins.append(page)
        hana = browser()
        launch(hana, platform.add('student-hana', [LEARNER], name='Hana Ito', target='/teleop'), '/teleop')
        status, people = api(gw, 'GET', '/api/people', token=ADMIN_TOKEN)
        assert status == 200
        named = {p['name']: p for p in people['people'] if p['kind'] == 'lti'}
        assert named['Hana Ito']['role'] == 'operator' and named['Hana Ito']['id'].startswith('lti-')
        assert 'student-hana' not in json.dumps(people)                      # the LMS's subject stays out
        assert http(gw, '/api/people').status == 401

        start = time.time() + 1
        slot = {'start': start, 'end': start + 600}
        status, booked = api(gw, 'POST', '/api/bookings', {'station': '/s02', **slot, 'for': 'hana ito'}, ADMIN_TOKEN)
        assert status == 201 and booked['name'] == 'Hana Ito' and not booked['mine'], booked
        status, why, _ = http(gw, '/api/bookings', method='POST', token=ADMIN_TOKEN,
                              json={'station': '/s01', **slot, 'for': 'Gil Ray'})
        why = why.decode()
        assert status == 409 and 'several people are named' in why and why.count('lti-') == 2, why
        gil = [p['id'] for p in people['people'] if p['name'] == 'Gil Ray']
        status, booked = api(gw, 'POST', '/api/bookings', {'station': '/s01', **slot, 'for': gil[0]}, ADMIN_TOKEN)
        assert status == 201 and booked['name'] == 'Gil Ray', booked

        # on her own pages the slot is hers, and her teleop page drives /s02 in it
        mine = hana.evaluate("fetch('/api/bookings', {credentials: 'same-origin'}).then((r) => r.json())")
        assert [b['station'] for b in mine['bookings'] if b['mine']] == ['/s02'], mine
        wait_for(lambda: api(gw, 'GET', '/api/bookings', token=ADMIN_TOKEN)[1]['now'] >= start,   # her slot is on
                 timeout=30, interval=0.2)
        hana.goto(platform.tool + '/teleop?ns=/s02')          # the tool's site, where her session is
        hana.wait_for_function("document.body?.dataset.connection === 'connected' && teleop.robotNs.mine === '/s02'",
                               timeout=30000)
        with Client(gw.ws_url, ADMIN_TOKEN) as watcher:
            watcher.subscribe('/s02/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
            hana.locator('body').click(position={'x': 5, 'y': 5})
            hana.keyboard.down('ArrowUp')
            watcher.expect(lambda m: m.get('op') == 'publish' and m['msg']['linear']['x'] > 0, timeout=15)
            hana.keyboard.up('ArrowUp')
        assert not hana.errors, hana.errors
    finally:
        platform.stop()
