"""The course loop against an LTI 1.3 platform that is not the project's own (PyPI's
``lti1p3platform``, served on loopback by tests/support/lti1p3.py): the roster in /class before any
launch (NRPS), a deep link that makes an exercise's gradebook column (its lineItem), students who
launch from it and reach (or miss) the goal on the sim, and the scores in that platform's gradebook
(AGS), one per attempt, none for anyone else, none from a browser's request.

One gateway for the module (``--auth --lti --exercises-dir``, turtlesim); launches go through
the tool's real /lti/login and /lti/launch with the state cookie, as a browser would send it.
"""

from __future__ import annotations

import json
import re
import types
import urllib.parse

import pytest

from tests.support.auth import TOKENS, login, tokens_toml
from tests.support.http import api, http
from tests.support.lti1p3 import INSTRUCTOR, LEARNER, Platform, form_of
from tests.support.lti_platform import write_tool_key
from tests.support.wait import wait_for
from tests.support.wsclient import Client, twist

EXERCISES = {
    'east': {'title': 'East of the start', 'time_limit': 30,
             'goal': {'all': [{'region': {'xmin': 7, 'xmax': 11, 'ymin': 0, 'ymax': 11}}, {'within': 25}]}},
    'nowhere': {'title': 'A corner nobody reaches', 'time_limit': 1.5,
                'goal': {'region': {'xmin': 0, 'xmax': 0.5, 'ymin': 0, 'ymax': 0.5}}},
    'corner': {'title': 'The far corner', 'time_limit': 2.5,
               'goal': {'region': {'xmin': 0, 'xmax': 1, 'ymin': 0, 'ymax': 1}}},
}
MEMBERS = [
    {'user_id': 'prof-ada', 'name': 'Ada Prof', 'roles': [INSTRUCTOR], 'status': 'Active'},
    {'user_id': 'stu-ben', 'name': 'Ben Student', 'roles': [LEARNER], 'status': 'Active'},
    {'user_id': 'stu-cleo', 'name': 'Cleo Student', 'roles': [LEARNER], 'status': 'Active'},
    {'user_id': 'stu-dan', 'name': 'Dan Gone', 'roles': [LEARNER], 'status': 'Inactive'},
]


course_state: dict = {}   # what a test leaves for the next (the tests of this module run in order)


@pytest.fixture(scope='module')
def course(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('lti1p3')
    write_tool_key(folder / 'tool.pem')
    platform = Platform()
    platform.members = [dict(m) for m in MEMBERS]
    (folder / 'tool.json').write_text(json.dumps(platform.tool_config('tool.pem')))
    (folder / 'tokens.toml').write_text(tokens_toml())
    exercises = folder / 'exercises'
    exercises.mkdir()
    for name, data in EXERCISES.items():
        (exercises / f'{name}.json').write_text(json.dumps(data))
    gw = start_gateway('--robot', 'turtlesim', '--auth', str(folder / 'tokens.toml'), '--lti', str(folder / 'tool.json'),
                       '--exercises-dir', str(exercises))
    platform.tool = gw.http_url.rstrip('/')
    yield gw, platform
    platform.stop()


def cookies(reply) -> dict:
    return dict(c.split(';', 1)[0].split('=', 1) for c in reply.headers.get_all('Set-Cookie') or [])


def launch(gw, platform: Platform, start: str) -> tuple[str, str]:
    """A launch through the tool's OIDC login, as a browser makes it: (the tool's page, its session cookie)."""
    at = types.SimpleNamespace(http_url=platform.issuer)
    to_login = http(at, start.removeprefix(platform.issuer))
    assert to_login.status == 302, to_login
    login_url = urllib.parse.urlsplit(to_login.headers['Location'])
    to_auth = http(gw, f'{login_url.path}?{login_url.query}')
    assert to_auth.status == 302, to_auth.body[:300]
    state = cookies(to_auth)
    auth = http(at, to_auth.headers['Location'].removeprefix(platform.issuer))
    assert auth.status == 200, auth.body[:500]
    action, fields = form_of(auth.body.decode())
    assert action == gw.http_url.rstrip('/') + '/lti/launch', action
    landed = http(gw, '/lti/launch', method='POST', data=urllib.parse.urlencode(fields).encode(),
                  headers={'Content-Type': 'application/x-www-form-urlencoded',
                           'Cookie': '; '.join(f'{k}={v}' for k, v in state.items())})
    assert landed.status == 200, landed.body[:500]
    session = cookies(landed).get('rosgate_session')
    return landed.body.decode(), f'rosgate_session={session}' if session else ''


def deep_link(gw, platform: Platform, exercise: str) -> str:
    """The teacher adds the exercise through deep linking; the resource link the platform made."""
    page, _ = launch(gw, platform, platform.add('prof-ada', [INSTRUCTOR], name='Ada Prof', kind='dl'))
    assert f'value="exercise:{exercise}"' in page, page[:1500]
    ticket = re.search(r'name="ticket" value="([^"]+)"', page).group(1)
    answer = http(gw, '/lti/deeplink', method='POST', headers={'Content-Type': 'application/x-www-form-urlencoded'},
                  data=urllib.parse.urlencode({'ticket': ticket, 'pick': f'exercise:{exercise}', 'as': 'blocks',
                                               'title': ''}).encode())
    assert answer.status == 200, answer.body[:500]
    action, fields = form_of(answer.body.decode())
    assert action == platform.url('/dl-return')
    links = set(platform.links)
    back = http(types.SimpleNamespace(http_url=platform.issuer), '/dl-return', method='POST',
                data=urllib.parse.urlencode(fields).encode(),
                headers={'Content-Type': 'application/x-www-form-urlencoded'})
    assert back.status == 200, back.body[:500]
    (link,) = set(platform.links) - links
    return link


def student(gw, platform: Platform, sub: str, name: str, link: str) -> str:
    page, session = launch(gw, platform, platform.add(sub, [LEARNER], name=name, link=link))
    assert session and '?exercise=' in page, page[:500]
    return session


def attempt(gw, session: str, exercise: str) -> str:
    status, started = api(gw, 'POST', f'/api/exercises/{exercise}/attempts',
                          {'station': '/turtle1', 'program': 'drive'}, headers={'Cookie': session})
    assert status == 201, started
    return started['attempt']


def ended(gw, session: str, attempt_id: str) -> dict:
    def done():
        status, body = api(gw, 'GET', f'/api/attempts/{attempt_id}', headers={'Cookie': session})
        assert status == 200, body
        return not body['live'] and body
    return wait_for(done, timeout=15, what=f'the end of attempt {attempt_id}')


def test_the_roster_is_in_the_class_view_before_any_launch(course, chromium):
    gw, platform = course
    assert not platform.launches                     # nobody launched: the roster came from memberships_urls
    ctx = chromium.new_context()
    try:
        name, value = login(gw, TOKENS['admin']).split('=', 1)
        ctx.add_cookies([{'name': name, 'value': value, 'url': gw.http_url}])
        page = ctx.new_page()
        page.goto(gw.http_url.rstrip('/') + '/class')
        page.wait_for_function("document.querySelector('#roster')?.dataset.members === '4'", timeout=15000)
        rows = page.eval_on_selector_all('#roster li', 'els => els.map(e => [e.textContent, e.dataset.role, '
                                                       'e.dataset.status])')
        assert sorted(rows) == [['Ada Prof · admin', 'admin', 'Active'],
                                ['Ben Student · operator', 'operator', 'Active'],
                                ['Cleo Student · operator', 'operator', 'Active'],
                                ['Dan Gone · operator · left the course', 'operator', 'Inactive']], rows
        assert page.is_visible('#roster')
        # the teacher's Refresh reads the platform again: a new member shows at once
        platform.members.append({'user_id': 'stu-eve', 'name': 'Eve New', 'roles': [LEARNER]})
        page.click('#roster .roster-refresh')
        page.wait_for_function("document.querySelector('#roster')?.dataset.members === '5'", timeout=15000)
        # the booking panel offers the members who never launched
        status, people = api(gw, 'GET', '/api/people', token=TOKENS['admin'])
        assert status == 200 and {'Ben Student', 'Eve New'} <= {p['name'] for p in people['people']}
        assert 'Dan Gone' not in {p['name'] for p in people['people']}
        assert api(gw, 'GET', '/api/roster', token=TOKENS['operator'])[0] == 403   # the teacher's alone
    finally:
        ctx.close()
        platform.members = [dict(m) for m in MEMBERS]


def test_a_student_reaching_the_goal_gets_exactly_one_score(course):
    gw, platform = course
    platform.members.append({'user_id': 'stu-fay', 'name': 'Fay Late', 'roles': [LEARNER]})
    link = deep_link(gw, platform, 'east')
    # the teacher's launch read the course's roster again, beside the launch
    wait_for(lambda: 'Fay Late' in {m['name'] for m in api(gw, 'GET', '/api/roster', token=TOKENS['admin'])[1]['members']},
             what='the roster read at the launch')
    item = platform.lineitems[platform.links[link]['lineitem']]
    assert (item['scoreMaximum'], item['label'], item['resourceId']) == (1, 'East of the start', 'east')
    assert platform.links[link]['custom'] == {'exercise': 'east'}
    assert platform.returned[-1][0]['url'].endswith('/?exercise=east')
    session = student(gw, platform, 'stu-ben', 'Ben Student', link)
    ws = Client(gw.ws_url, additional_headers={'Cookie': session})
    try:
        attempt_id = attempt(gw, session, 'east')

        def driven():
            ws.publish('/turtle1/cmd_vel', twist(x=2.0), type='geometry_msgs/msg/Twist')
            status, body = api(gw, 'GET', f'/api/attempts/{attempt_id}', headers={'Cookie': session})
            return status == 200 and not body['live']
        wait_for(driven, timeout=15, what='the goal reached')
        ws.publish('/turtle1/cmd_vel', twist(), type='geometry_msgs/msg/Twist')
    finally:
        ws.ws.close()
    result = ended(gw, session, attempt_id)
    assert result['passed'] is True and result['score'] == 1.0 and result['why'] == 'goal'
    scores = wait_for(lambda: platform.scores(link), what='the score in the platform\'s gradebook')
    assert len(scores) == 1 and scores[0]['userId'] == 'stu-ben', scores
    assert (scores[0]['scoreGiven'], scores[0]['scoreMaximum']) == (1.0, 1.0)
    assert (scores[0]['activityProgress'], scores[0]['gradingProgress']) == ('Completed', 'FullyGraded')
    assert scores[0]['comment'].startswith('passed (goal)')
    course_state['east'] = (link, session, attempt_id)


def test_a_link_that_kept_only_the_line_item_is_graded_by_its_resource_id(course):
    """A platform that kept neither the custom parameter nor the link's query: the line item's
    resourceId (what the deep link gave it) names the exercise, read from the platform."""
    gw, platform = course
    link = platform.add_link('East, added by hand', lineitem={'scoreMaximum': 1, 'label': 'East', 'resourceId': 'east'})
    page, session = launch(gw, platform, platform.add('stu-cleo', [LEARNER], name='Cleo Student', link=link))
    assert session, page[:300]
    result = ended(gw, session, attempt(gw, session, 'east'))   # turtle1 is east already: passed at its first pose
    assert result['passed'] is True
    scores = wait_for(lambda: platform.scores(link), what='the score of the hand-made link')
    assert [(s['userId'], s['scoreGiven']) for s in scores] == [('stu-cleo', 1.0)]


def test_a_missed_goal_is_posted_as_failed_and_nothing_for_who_did_not_launch(course):
    gw, platform = course
    link = deep_link(gw, platform, 'nowhere')
    before = list(platform.gradebook)
    # alice (a token, no launch) misses the goal too: her result is kept, no score goes anywhere
    status, started = api(gw, 'POST', '/api/exercises/nowhere/attempts', {'station': '/turtle1', 'program': 'x'},
                          token=TOKENS['operator'])
    assert status == 201, started
    alices = wait_for(lambda: (r := api(gw, 'GET', f'/api/attempts/{started["attempt"]}', token=TOKENS['operator'])[1])
                      and not r['live'] and r, what='alice\'s attempt ended')
    assert alices['passed'] is False
    session = student(gw, platform, 'stu-cleo', 'Cleo Student', link)
    result = ended(gw, session, attempt(gw, session, 'nowhere'))
    assert result['passed'] is False and result['score'] == 0.0 and result['why'] == 'time'
    scores = wait_for(lambda: platform.scores(link), what='the failed attempt\'s score')
    assert len(scores) == 1 and scores[0]['userId'] == 'stu-cleo'
    assert scores[0]['scoreGiven'] == 0.0 and scores[0]['comment'].startswith('failed (time)')
    # the comment names the part of the goal that was missed, for the teacher in the gradebook
    assert scores[0]['comment'].startswith('failed (time): region x 0..0.5, y 0..0.5 not reached, attempt '), scores
    assert (scores[0]['activityProgress'], scores[0]['gradingProgress']) == ('Completed', 'FullyGraded')
    assert platform.gradebook[len(before):] == [(platform.links[link]['lineitem'], scores[0])]   # alice: none


def test_a_score_cannot_be_forged_or_replayed_from_the_browser(course):
    gw, platform = course
    link, session, attempt_id = course_state['east']
    # the ended attempt cannot be ended again, nor a score sent by any route
    assert api(gw, 'POST', f'/api/attempts/{attempt_id}/stop', {}, headers={'Cookie': session})[0] == 404
    forged = {'attempt': attempt_id, 'score': 1.0, 'scoreGiven': 1, 'passed': True, 'exercise': 'east'}
    for path in ('/api/scores', '/api/grades', f'/api/attempts/{attempt_id}', '/api/exercise-results',
                 '/api/exercises/east', '/lti/scores', '/api/roster'):
        status = http(gw, path, method='POST', json=forged, headers={'Cookie': session}).status
        assert status in (403, 404, 405), (path, status)
    # a pose published by the student's own client is not the robot's: the goal is not reached with it
    corner = deep_link(gw, platform, 'corner')
    session2 = student(gw, platform, 'stu-ben', 'Ben Student', corner)
    ws = Client(gw.ws_url, additional_headers={'Cookie': session2})
    try:
        started = attempt(gw, session2, 'corner')
        fake = {'x': 0.5, 'y': 0.5, 'theta': 0.0, 'linear_velocity': 0.0, 'angular_velocity': 0.0}
        assert ws.refusal({'op': 'advertise', 'topic': '/turtle1/pose', 'type': 'turtlesim/msg/Pose'}) is None
        refused = ws.refusal({'op': 'publish', 'topic': '/turtle1/pose', 'msg': fake, 'id': 'fake-pose-1'})
        assert refused is not None and refused['id'] == 'fake-pose-1' and 'live exercise attempt' in refused['msg'], refused
    finally:
        ws.ws.close()
    result = ended(gw, session2, started)
    assert result['passed'] is False and result['why'] == 'time', result
    scores = wait_for(lambda: platform.scores(corner), what='the corner attempt\'s score')
    assert [s['scoreGiven'] for s in scores] == [0.0]
    assert len(platform.scores(link, 'stu-ben')) == 1          # still one score for the east attempt
