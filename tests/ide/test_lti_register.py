"""LTI Dynamic Registration 1.0 against a platform that is not the project's own (tests/support/
lti1p3.py: PyPI's ``lti1p3platform`` for launches, grades and the roster, and the registration
endpoints as Moodle 4.x has them): the gateway starts with an --lti file naming no platform; an
admin makes a registration URL at /lti/config; the LMS admin's page opens it in a frame with its
``openid_configuration`` and ``registration_token``; the tool registers itself and closes the
frame with ``org.imsglobal.lti.close`` (in Chromium). The registered tool then takes a deep link, a
student's launch, and posts the attempt's grade to the platform's gradebook. The URL is good once
and only an admin's; /lti/config says how to turn on grades and the roster."""

from __future__ import annotations

import json
import re
from urllib.parse import urlencode

import pytest

from tests.ide.test_lti_course import attempt, deep_link, ended, student
from tests.support.auth import TOKENS, login, tokens_toml
from tests.support.http import http
from tests.support.lti1p3 import Platform
from tests.support.wait import wait_for

EXERCISES = {'anywhere': {'title': 'Anywhere at all', 'time_limit': 20,
                          'goal': {'region': {'xmin': 0, 'xmax': 11.1, 'ymin': 0, 'ymax': 11.1}}}}
FORM = {'Content-Type': 'application/x-www-form-urlencoded'}


@pytest.fixture(scope='module')
def lab(launch, tmp_path_factory):
    folder = tmp_path_factory.mktemp('lti-dr')
    (folder / 'tool.json').write_text('{}')          # no platform yet
    (folder / 'tokens.toml').write_text(tokens_toml())
    (folder / 'ex').mkdir()
    for name, data in EXERCISES.items():
        (folder / 'ex' / f'{name}.json').write_text(json.dumps(data))
    gw = launch('--robot', 'turtlesim', '--auth', str(folder / 'tokens.toml'), '--lti', str(folder / 'tool.json'),
                '--exercises-dir', str(folder / 'ex'))
    platform = Platform(client_id='not-registered-yet')
    yield gw, platform
    platform.stop()


def registration_url(gw, token: str) -> tuple[int, str]:
    """(status, the URL or the page) of an admin's POST /lti/register/new."""
    reply = http(gw, '/lti/register/new', method='POST', data=b'', headers={**FORM, 'Cookie': login(gw, token)})
    found = re.search(r'<code id="url">([^<]+)</code>', reply.body.decode())
    return reply.status, (found.group(1).replace('&amp;', '&') if found else reply.body.decode())


def test_config_names_grades_and_the_roster(lab):
    gw, _ = lab
    page = http(gw, '/lti/config').body.decode()
    for words in ('Assignment and Grade Services', 'Names and Role Provisioning', 'auth_token_url',
                  'memberships_urls', 'Dynamic Registration', 'Moodle', 'Canvas', '/mod/lti/token.php',
                  '/login/oauth2/token', 'Can create and update submission results',
                  'Can retrieve user data associated with the context'):
        assert words in page, words
    assert 'id="new-registration"' not in page          # only an admin makes a registration URL
    admin = http(gw, '/lti/config', headers={'Cookie': login(gw, TOKENS['admin'])}).body.decode()
    assert 'id="new-registration"' in admin


def test_only_an_admin_makes_a_registration_url(lab):
    gw, _ = lab
    assert registration_url(gw, TOKENS['operator'])[0] == 403
    reply = http(gw, '/lti/register/new', method='POST', data=b'', headers=FORM)
    assert reply.status == 403, reply
    # from another site's page, even an admin's session makes none
    reply = http(gw, '/lti/register/new', method='POST', data=b'',
                 headers={**FORM, 'Cookie': login(gw, TOKENS['admin']), 'Origin': 'https://evil.example',
                          'Sec-Fetch-Site': 'cross-site'})
    assert reply.status == 403, reply


def test_a_made_up_url_registers_nothing(lab):
    gw, platform = lab
    platform.registration_page('x')       # a live registration token, as if an LMS had one
    reply = http(gw, '/lti/register?ticket=made-up&' + urlencode_config(platform))
    assert reply.status == 403 and 'admin' in reply.body.decode(), reply
    assert not platform.registered


def urlencode_config(platform) -> str:
    return urlencode({'openid_configuration': platform.url('/.well-known/openid-configuration'),
                      'registration_token': platform.registration_token or ''})


def test_the_platform_registers_the_tool_in_one_step_and_it_posts_a_grade(lab, chromium):
    gw, platform = lab
    status, url = registration_url(gw, TOKENS['admin'])
    assert status == 200 and '/lti/register?ticket=' in url, url
    ctx = chromium.new_context()
    try:
        page = ctx.new_page()
        page.goto(platform.registration_page(url))
        page.wait_for_function("document.body.dataset.closed === 'yes'", timeout=30000)
    finally:
        ctx.close()
    (sent,) = platform.registered
    tool = sent['https://purl.imsglobal.org/spec/lti-tool-configuration']
    base = gw.http_url.rstrip('/')
    assert sent['initiate_login_uri'] == f'{base}/lti/login' and sent['redirect_uris'] == [f'{base}/lti/launch']
    assert sent['jwks_uri'] == f'{base}/lti/jwks'
    scopes = sent['scope'].split()
    assert any(s.endswith('/scope/score') for s in scopes) and any('contextmembership' in s for s in scopes)
    assert {m['type'] for m in tool['messages']} == {'LtiResourceLinkRequest', 'LtiDeepLinkingRequest'}
    config = http(gw, '/lti/config').body.decode()
    assert platform.issuer in config and platform.client_id in config and platform.deployment in config

    # the URL was good once
    platform.registration_page(url)
    again = http(gw, url.removeprefix(base) + '&' + urlencode_config(platform))
    assert again.status == 403, again
    assert len(platform.registered) == 1

    # the registered tool: a deep link adds the exercise, a student launches it, her score reaches the gradebook
    link = deep_link(gw, platform, 'anywhere')
    session = student(gw, platform, 'stu-ada', 'Ada Student', link)
    done = ended(gw, session, attempt(gw, session, 'anywhere'))
    assert done['passed'] is True, done
    scores = wait_for(lambda: platform.scores(link, 'stu-ada'), timeout=30, what='the score in the gradebook')
    assert scores[0]['scoreGiven'] == 1.0 and scores[0]['gradingProgress'] == 'FullyGraded', scores


def test_a_gateway_started_on_the_same_store_knows_the_platform(lab, launch, tmp_path):
    """The registration is kept in the store: a gateway started on it (a restart, or another gateway
    of a fleet) takes launches from that platform, its --lti file still naming none."""
    gw, platform = lab
    assert platform.registered, 'run after the registration test'
    (tmp_path / 'tool.json').write_text('{}')
    (tmp_path / 'tokens.toml').write_text(tokens_toml())
    db = f"sqlite:///{gw.data_home}/rosgate/rosgate.db"
    other = launch('--robot', 'none', '--auth', str(tmp_path / 'tokens.toml'), '--lti', str(tmp_path / 'tool.json'),
                   '--db', db)
    query = urlencode({'iss': platform.issuer, 'login_hint': 'stu-bo', 'client_id': platform.client_id,
                       'lti_deployment_id': platform.deployment, 'target_link_uri': other.http_url})
    reply = wait_for(lambda: (r := http(other, f'/lti/login?{query}')).status == 302 and r, timeout=30,
                     what='the other gateway taking the registered platform')
    assert reply.headers['Location'].startswith(platform.url('/auth')), reply.headers['Location']
