"""The class view's attempts on a single robot (``--robot turtlesim``, no --fleet), in Chromium: one
station tile for the robot ('/', not "/turtle1" and "/world"), and each student's attempts by
person in the Attempts section, whoever they are: two browsers without sign-in (each its own
person, named as its page names it), and people signed in by token. The attempts are checked
by the gateway on /turtle1/pose; the page is the teacher's."""

from __future__ import annotations

import json

import pytest

from tests.support.auth import TOKENS, login, tokens_toml
from tests.support.http import api, http
from tests.support.ide import TABLET
from tests.support.wait import wait_for

ANYWHERE = {'title': 'Be in the world', 'time_limit': 20,   # pose_topic left at 'pose': turtle1's is found
            'titles': {'es': 'Estar en el mundo'},
            'goal': {'region': {'xmin': 0, 'xmax': 11.1, 'ymin': 0, 'ymax': 11.1}}}
CORNER = {'title': 'The far corner', 'time_limit': 1, 'pose_topic': 'turtle1/pose',
          'goal': {'region': {'xmin': 0, 'xmax': 0.2, 'ymin': 0, 'ymax': 0.2}}}
BROWSER = {'ada': 'browser-id-of-ada-0001', 'bo': 'browser-id-of-bo-00002'}


def exercises(folder):
    folder.mkdir()
    (folder / 'anywhere.json').write_text(json.dumps(ANYWHERE))
    (folder / 'corner.json').write_text(json.dumps(CORNER))
    return str(folder)


@pytest.fixture(scope='module')
def single(launch, tmp_path_factory):
    return launch('--robot', 'turtlesim', '--exercises-dir', exercises(tmp_path_factory.mktemp('single') / 'ex'))


@pytest.fixture(scope='module')
def signed(launch, tmp_path_factory):
    folder = tmp_path_factory.mktemp('signed')
    (folder / 'tokens.toml').write_text(tokens_toml())
    return launch('--robot', 'turtlesim', '--auth', str(folder / 'tokens.toml'),
                  '--exercises-dir', exercises(folder / 'ex'))


def attempt(gw, exercise: str, *, headers: dict, body: dict | None = None) -> dict:
    status, started = api(gw, 'POST', f'/api/exercises/{exercise}/attempts',
                          {'station': '', 'program': f'{exercise} program', **(body or {})}, headers=headers)
    assert status == 201, started

    def done():
        status, got = api(gw, 'GET', f'/api/attempts/{started["attempt"]}', headers=headers)
        assert status == 200, got
        return None if got['live'] else got
    return wait_for(done, what=f'attempt {started["attempt"]} ended')


def class_page(chromium, gw, cookie: str = ''):
    ctx = chromium.new_context(viewport=TABLET)
    if cookie:
        name, value = cookie.split('=', 1)
        ctx.add_cookies([{'name': name, 'value': value, 'url': gw.http_url}])
    page = ctx.new_page()
    errors: list = []
    page.on('pageerror', lambda e: errors.append(str(e)))
    page.on('console', lambda m: m.type == 'error' and errors.append(m.text))
    page.goto(gw.http_url + 'class')
    return ctx, page, errors


def person(page, key: str) -> str:
    return f"#attempts article.person[data-person='{key}']"


def test_a_single_robot_is_one_station_and_each_browser_is_a_person(single, chromium):
    gw = single
    ada = attempt(gw, 'anywhere', headers={'Cookie': f'rosgate_browser={BROWSER["ada"]}'}, body={'name': 'ada'})
    assert ada['passed'] is True and ada['name'] == 'ada' and ada['person'].startswith('browser-'), ada
    assert BROWSER['ada'] not in json.dumps(ada)          # the browser's id (what holds a station) is not told
    missed = attempt(gw, 'corner', headers={'Cookie': f'rosgate_browser={BROWSER["ada"]}'}, body={'name': 'ada'})
    assert missed['passed'] is False and missed['person'] == ada['person']
    bo = attempt(gw, 'anywhere', headers={'Cookie': f'rosgate_browser={BROWSER["bo"]}'})
    assert bo['person'] != ada['person'] and bo['name'].startswith('browser '), bo

    ctx, page, errors = class_page(chromium, gw)
    try:
        page.wait_for_function("document.body.dataset.tiles === '1'", timeout=30000)
        assert page.eval_on_selector_all('article.tile', 'els => els.map(e => e.dataset.ns)') == ['/']
        page.wait_for_selector(f"{person(page, ada['person'])}[data-passed='1']", timeout=30000)
        assert page.inner_text(f"{person(page, ada['person'])} h4") == 'ada'
        passed = page.locator(f"{person(page, ada['person'])} li[data-exercise='anywhere']")
        assert passed.get_attribute('data-passed') is not None
        assert 'Be in the world' in passed.inner_text() and 'best 100% (passed)' in passed.inner_text()
        corner = page.locator(f"{person(page, ada['person'])} li[data-exercise='corner']")
        assert corner.get_attribute('data-passed') is None and 'not passed' in corner.inner_text()
        replay = passed.locator('a').get_attribute('href')
        assert replay.endswith('.mcap'), replay
        got = ctx.request.get(gw.http_url + replay)
        assert got.ok and got.body()[:5] == b'\x89MCAP', got.status
        assert page.inner_text(f"{person(page, bo['person'])} h4") == bo['name']
        assert page.locator('#attempts article.person').count() == 2
        assert not errors, errors
    finally:
        ctx.close()


def test_people_signed_in_by_token_on_a_single_robot(signed, chromium):
    gw = signed
    alice = attempt(gw, 'anywhere', headers={'Authorization': f'Bearer {TOKENS["operator"]}'})
    bob = attempt(gw, 'corner', headers={'Authorization': f'Bearer {TOKENS["operator2"]}'})
    assert (alice['name'], bob['name']) == ('alice', 'bob')
    # a student reads only her own results; the teacher reads the class's
    status, mine = api(gw, 'GET', '/api/exercise-results', headers={'Authorization': f'Bearer {TOKENS["operator"]}'})
    assert status == 200 and {r['name'] for r in mine['results']} == {'alice'}, mine
    ctx, page, errors = class_page(chromium, gw, login(gw, TOKENS['admin']))
    try:
        page.wait_for_selector(f"{person(page, alice['person'])}[data-passed='1']", timeout=30000)
        page.wait_for_selector(f"{person(page, bob['person'])}[data-passed='0'] li[data-exercise='corner']",
                               timeout=30000)
        assert page.inner_text(f"{person(page, bob['person'])} h4") == 'bob'
        assert http(gw, '/api/exercise-results').status == 401   # nobody's results without sign-in
        assert not errors, errors
    finally:
        ctx.close()
