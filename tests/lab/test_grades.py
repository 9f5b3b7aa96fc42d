"""Scores reach a platform over real HTTP once per attempt, after the LMS comes back, and only for a launch."""

from __future__ import annotations

import asyncio
import json
import socket
import time

import jwt
import pytest
from cryptography.hazmat.primitives.asymmetric import rsa
from tornado import httpserver, web

from gateway.lab import grades
from gateway.auth.lti import CLAIM, LtiConfig, Registration
from gateway.store import Store

ISS = 'https://lms.test'


class Platform:
    """A platform's token and score endpoints on loopback: checks the tool's signed assertion."""

    def __init__(self, tool_public):
        self.scores, self.tokens, self.public = [], set(), tool_public
        plat = self

        class Token(web.RequestHandler):
            def post(self):
                a = self.get_body_argument('client_assertion')
                claims = jwt.decode(a, plat.public, algorithms=['RS256'], audience=plat.url('/token'))
                assert claims['sub'] == 'tool' and self.get_body_argument('grant_type') == 'client_credentials'
                assert grades.SCOPE_SCORE in self.get_body_argument('scope').split()
                tok = 'tok-' + claims['jti']
                plat.tokens.add(tok)
                self.write({'access_token': tok, 'token_type': 'Bearer', 'expires_in': 300})

        class Scores(web.RequestHandler):
            def post(self, item):
                if self.request.headers.get('Authorization', '')[7:] not in plat.tokens:
                    raise web.HTTPError(401)
                plat.scores.append((item, json.loads(self.request.body)))

        self.app = web.Application([(r'/token', Token), (r'/lineitems/(\w+)/scores', Scores)])
        sock = socket.socket()
        sock.bind(('127.0.0.1', 0))
        self.port = sock.getsockname()[1]
        sock.close()
        self.server = None

    def url(self, path):
        return f'http://127.0.0.1:{self.port}{path}'

    def start(self):
        self.server = httpserver.HTTPServer(self.app)
        self.server.listen(self.port, '127.0.0.1')

    def stop(self):
        self.server.stop()


@pytest.fixture
def setup(tmp_path):
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    plat = Platform(key.public_key())
    reg = Registration(ISS, 'tool', plat.url('/auth'), None, {'keys': []}, ('d1',), plat.url('/token'))
    config = LtiConfig([reg], {'k1': key})
    store = Store(f'sqlite:///{tmp_path / "g.db"}')
    yield plat, config, store
    store.close()


def launch(sub, link, item, exercise=None):
    claims = {'iss': ISS, 'aud': 'tool', 'sub': sub, CLAIM + 'resource_link': {'id': link},
              grades.AGS_CLAIM: {'scope': [grades.SCOPE_SCORE], 'lineitem': item}}
    if exercise:
        claims[CLAIM + 'custom'] = {'exercise': exercise}
    return claims


def ended(attempt, person, passed, score, why):
    from gateway.lab.exercises import AttemptResult
    return AttemptResult(attempt=attempt, exercise='east', person=person, name=person, station='/turtle1',
                         passed=passed, score=score, why=why, started_at=time.time() - 5, ended_at=time.time(),
                         program='forward')


def test_the_checkers_hook_posts_each_ended_attempt_once_for_its_launch(setup):
    asyncio.run(_hook(*setup))


async def _hook(plat, config, store):
    plat.start()
    outbox = grades.Outbox(store, config)
    await grades.remember_launch(store, 'p1', launch('s1', 'rl-east', plat.url('/lineitems/east'), 'east'))
    assert await outbox.queue('p1', 'east', ended('a1', 'p1', True, 1.0, 'goal')) is True
    assert await outbox.queue('p1', 'east', ended('a1', 'p1', True, 1.0, 'goal')) is False     # never twice
    assert await outbox.queue('p1', 'east', ended('a2', 'p1', False, 0.4, 'time')) is True     # failed: posted too
    assert await outbox.queue('p2', 'east', ended('a3', 'p2', True, 1.0, 'goal')) is False     # never launched
    assert await outbox.queue('p1', 'west', ended('a4', 'p1', True, 1.0, 'goal')) is False     # not this exercise
    assert [(item, s['scoreGiven'], s['comment'].split(' (')[0]) for item, s in plat.scores] == \
        [('east', 1.0, 'passed'), ('east', 0.4, 'failed')]
    assert all(s['activityProgress'] == 'Completed' and s['gradingProgress'] == 'FullyGraded' for _, s in plat.scores)
    plat.stop()


def test_one_score_per_attempt_and_only_after_a_launch(setup):
    asyncio.run(_one_score(*setup))


async def _one_score(plat, config, store):
    plat.start()
    assert await grades.remember_launch(store, 'p1', launch('s1', 'rl1', plat.url('/lineitems/li1')))
    assert await grades.post_result(store, 'p1', 'rl1', 0.75, 'att-1') is True
    assert await grades.post_result(store, 'p1', 'rl1', 0.75, 'att-1') is False
    with pytest.raises(grades.GradeError, match='did not launch'):
        await grades.post_result(store, 'p2', 'rl1', 1.0, 'att-2')
    with pytest.raises(grades.GradeError, match='did not launch'):
        await grades.post_result(store, 'p1', 'rl-other', 1.0, 'att-3')
    outbox, other = grades.Outbox(store, config), grades.Outbox(store, config)   # two gateways, one database
    assert sorted(await asyncio.gather(outbox.flush(), other.flush())) == [0, 1]
    assert await outbox.flush() == 0
    assert len(plat.scores) == 1
    item, score = plat.scores[0]
    assert item == 'li1' and score['userId'] == 's1' and score['scoreGiven'] == 0.75
    assert score['scoreMaximum'] == 1.0 and score['gradingProgress'] == 'FullyGraded'
    plat.stop()


def test_lms_down_then_back(setup):
    asyncio.run(_down_then_back(*setup))


async def _down_then_back(plat, config, store):
    await grades.remember_launch(store, 'p1', launch('s1', 'rl1', plat.url('/lineitems/li1')))
    await grades.post_result(store, 'p1', 'rl1', 1.0, 'att-9', now=1000.0)
    outbox = grades.Outbox(store, config)
    assert await outbox.flush(now=1000.0) == 0          # the LMS is down
    assert await outbox.flush(now=1001.0) == 0          # backing off
    plat.start()
    assert await outbox.flush(now=1000.0 + grades.BACKOFF_FIRST) == 1
    assert [s['scoreGiven'] for _, s in plat.scores] == [1.0]
    plat.stop()


def test_roster_and_a_student_who_left_cannot_book(setup):
    asyncio.run(_roster(*setup))


async def _roster(plat, config, store):
    from gateway.auth import courses
    from gateway.lab import roster
    from gateway.rules.bookings import BookingError, BookingLimits, Timetable
    from gateway.auth.lti import identity_of
    listed = [{'user_id': 's1', 'name': 'Ada', 'roles': ['Learner'], 'status': 'Active'},
              {'user_id': 's2', 'name': 'Bob', 'roles': ['Learner'], 'status': 'Active'}]

    class Members(web.RequestHandler):
        def get(self):
            if self.request.headers.get('Authorization', '')[7:] not in plat.tokens:
                raise web.HTTPError(401)
            self.set_header('Content-Type', roster.MEMBERSHIPS)
            self.write(json.dumps({'context': {'id': 'c1'}, 'members': listed}))
    plat.app.add_handlers(r'.*', [(r'/members', Members)])
    original = grades.SCOPE_SCORE
    plat.start()
    grades.SCOPE_SCORE = roster.SCOPE_MEMBERSHIPS   # the test platform checks this scope is asked for
    try:
        assert await roster.fetch(store, config, config.registrations[0], plat.url('/members')) == 2
        assert sorted(m['name'] for m in await courses.members(store)) == ['Ada', 'Bob']
        bob = identity_of({'iss': ISS, 'sub': 's2'}).key
        assert not await courses.has_left(store, bob)
        listed[1]['status'] = 'Inactive'
        await roster.fetch(store, config, config.registrations[0], plat.url('/members'))
        assert await courses.has_left(store, bob)
        del listed[1]
        await roster.fetch(store, config, config.registrations[0], plat.url('/members'))
        assert await courses.has_left(store, bob) and await courses.has_left(store, f"user {bob}")   # as bookings key it
        timetable = Timetable(store, BookingLimits())
        start = time.time() + 600
        with pytest.raises(BookingError) as refused:
            await timetable.add('s01', bob, 'Bob', start, start + 900)
        assert refused.value.status == 403 and 'no longer a member of this course' in refused.value.message
        ada = identity_of({'iss': ISS, 'sub': 's1'}).key
        assert (await timetable.add('s01', ada, 'Ada', start, start + 900)).id is not None
    finally:
        grades.SCOPE_SCORE = original
        plat.stop()
