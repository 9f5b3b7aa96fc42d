"""The class view's exercise results, in Chromium: a student on her fleet station passes an
exercise (checked by the gateway on /s01/turtle1/pose) and then misses another; the teacher's
/class shows on her tile the passed mark, best and last attempts and the program as it ran."""

from __future__ import annotations

import json

import pytest

from tests.support.http import api
from tests.support.ide import TABLET
from tests.support.lesson import TOKENS, on_station, open_ide, tokens_file
from tests.support.wait import wait_for

ANYWHERE = {'title': 'Be in the world', 'time_limit': 20,
            'goal': {'region': {'xmin': 0, 'xmax': 11.1, 'ymin': 0, 'ymax': 11.1}}}
CORNER = {'title': 'The far corner', 'time_limit': 1,
          'goal': {'region': {'xmin': 0, 'xmax': 0.2, 'ymin': 0, 'ymax': 0.2}}}


@pytest.fixture
def lab(start_gateway, tmp_path):
    folder = tmp_path / 'exercises'
    folder.mkdir()
    (folder / 'anywhere.json').write_text(json.dumps(ANYWHERE))
    (folder / 'corner.json').write_text(json.dumps(CORNER))
    return start_gateway('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--auth', tokens_file(tmp_path),
                         '--exercises-dir', str(folder))


def finished(gw, attempt: str, token: str) -> dict:
    def done():
        status, body = api(gw, 'GET', f'/api/attempts/{attempt}', token=token)
        assert status == 200, body
        return None if body['live'] else body
    return wait_for(done, what=f'attempt {attempt} ended')


def test_the_teacher_sees_the_passed_mark(lab, tablets, chromium):
    gw = lab
    ada = open_ide(tablets(gw, 'ada'), gw)
    on_station(ada, '/s01')
    # another student cannot start an attempt on ada's station (it would be graded for her)
    status, body = api(gw, 'POST', '/api/exercises/anywhere/attempts', {'station': '/s01/turtle1'}, token=TOKENS['bo'])
    assert status == 409, body
    status, first = api(gw, 'POST', '/api/exercises/anywhere/attempts',
                        {'station': '/s01/turtle1', 'program': 'print("here")'}, token=TOKENS['ada'])
    assert status == 201, first
    assert finished(gw, first['attempt'], TOKENS['ada'])['passed'] is True
    status, second = api(gw, 'POST', '/api/exercises/corner/attempts',
                         {'station': '/s01/turtle1', 'program': 'wait'}, token=TOKENS['ada'])
    assert status == 201, second
    assert finished(gw, second['attempt'], TOKENS['ada'])['why'] == 'time'

    ctx = chromium.new_context(viewport=TABLET)
    try:
        errors: list = []
        page = ctx.new_page()
        page.on('pageerror', lambda e: errors.append(str(e)))
        r = ctx.request.post(gw.http_url + 'login', form={'token': TOKENS['teacher'], 'next': '/whoami'})
        assert r.ok, r.status
        page.goto(gw.http_url + 'class')
        tile = "article.tile[data-ns='/s01']"
        page.wait_for_selector(f"{tile}[data-owner='ada'][data-passed='1']", timeout=30000)
        passed = page.locator(f"{tile} .exercises li[data-exercise='anywhere']")
        assert passed.get_attribute('data-passed') is not None
        assert passed.locator('.mark').inner_text() == '✓'
        assert 'best 100% (passed)' in passed.inner_text()
        missed = page.locator(f"{tile} .exercises li[data-exercise='corner']")
        assert missed.get_attribute('data-passed') is None and missed.locator('.mark').inner_text() == '✗'
        assert 'not passed' in missed.inner_text()
        passed.locator('summary').click()
        assert passed.locator('pre').inner_text() == 'print("here")'
        # the replay: the attempt's recording, which the teacher's session downloads
        replay = passed.locator('a').get_attribute('href')
        assert replay.endswith('.mcap'), replay
        got = ctx.request.get(gw.http_url + replay)
        assert got.ok and got.body()[:5] == b'\x89MCAP', got.status
        assert page.locator("article.tile[data-ns='/s02'] .exercises").is_hidden()
        assert not errors, errors
    finally:
        ctx.close()
