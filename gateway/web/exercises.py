"""Exercises and their attempts over HTTP (``gateway.lab`` does the checking):

GET  /api/exercises                 -> {"exercises": [...], "problems": [...]}   (anyone who may read)
GET  /api/exercises/ID              -> the exercise (its start program, goal, time limit)
POST /api/exercises  {"id", ...}    -> saved into --exercises-dir (admins)
POST /api/exercises/ID/attempts {"station": NS, "program": TEXT, "name": NAME}
                                    -> {"attempt": ATTEMPT_ID}: the goal is now watched on NS's topics;
                                       the attempt is the signed-in person's, else this browser's
                                       (NAME: how the page names its student; ``exercises.attempt_person``)
GET  /api/attempts/ATTEMPT_ID       -> {"live": true} while it runs, else its result (the starter or an admin)
POST /api/attempts/ATTEMPT_ID/stop  -> the attempt ends ("stopped"), its result
GET  /api/exercise-results[?exercise=ID][&person=KEY][&summary=1]
                                    -> {"results": [...], "summary": [{person, exercise, best, last, attempts}]}
                                       (summary=1: the summary alone)

Results are private: a student reads only their own (another's ``person`` is a 403); an admin
reads everyone's. An attempt may be started only on a station the caller could run a program on
(not another person's station, nor over another's live attempt), since it is graded for them, and
within the per-person caps: ``rules.attempts`` decides, with the status that says why (409, 429).
"""

from __future__ import annotations

import tornado.web

from ..lab import results
from ..lab.exercises import Checker, ExerciseError, Library, attempt_person, public
from ..rules.attempts import AttemptRule
from ..rules.stations import person_of
from ..rules.access import Action, Area, allowed
from ..store import Store
from .api import JsonHandler, authorize, authorized, body_json

MAX_BODY = 512 * 1024


def _key(identity) -> str:
    return identity.owner if identity is not None else 'anyone'


class ExercisesHandler(JsonHandler):
    def initialize(self, library: Library) -> None:
        self.library = library

    @authorized(Area.EXERCISES)
    def get(self, ex_id: str | None = None) -> None:
        try:
            if ex_id is None:
                found, problems = self.library.all()
                self.finish({'exercises': [public(e) for e in found], 'problems': problems})
                return
            ex = self.library.get(ex_id)
        except ExerciseError as e:
            raise tornado.web.HTTPError(500, str(e)) from None
        if ex is None:
            raise tornado.web.HTTPError(404, f'no exercise {ex_id[:64]!r}')
        self.finish(public(ex))

    def post(self, ex_id: str | None = None) -> None:
        if ex_id is not None:
            raise tornado.web.HTTPError(405, 'POST /api/exercises with the id in the body')
        self.identity = authorize(self, Area.EXERCISES)
        body = body_json(self, MAX_BODY)
        try:
            ex = self.library.save(str(body.get('id', '')), body)
        except ExerciseError as e:
            raise tornado.web.HTTPError(400, str(e)) from None
        self.set_status(201)
        self.finish(public(ex))


class AttemptsHandler(JsonHandler):
    def initialize(self, library: Library, checker: Checker, attempts: AttemptRule) -> None:
        self.library, self.checker, self.attempts = library, checker, attempts

    @authorized(Area.ATTEMPTS)
    def post(self, ex_id: str) -> None:
        identity = self.identity
        body = body_json(self, MAX_BODY)
        try:
            ex = self.library.get(ex_id)
        except ExerciseError as e:
            raise tornado.web.HTTPError(500, str(e)) from None
        if ex is None:
            raise tornado.web.HTTPError(404, f'no exercise {ex_id[:64]!r}')
        station, program, name = body.get('station', ''), body.get('program', ''), body.get('name', '')
        if not isinstance(station, str) or not isinstance(program, str):
            raise tornado.web.HTTPError(400, '"station" is a namespace and "program" the program\'s text')
        if not isinstance(name, str):
            raise tornado.web.HTTPError(400, '"name" is the student\'s name as the page has it (without sign-in)')
        ns = '/' + station.strip('/') if station.strip('/') else ''
        person = person_of(identity, self.request.cookies) or ''
        rule = self.attempts
        rule.start_refusal(identity, person, ns)    # another's station or live attempt, past a cap: its status
        browser = person[len('browser '):] if person.startswith('browser ') else None
        try:
            attempt = self.checker.start(ex, identity, ns, program, person, attempt_person(identity, browser, name))
        except LookupError as e:
            raise tornado.web.HTTPError(409, str(e.args[0])) from None
        rule.started(person)
        self.set_status(201)
        self.finish({'attempt': attempt.id, 'exercise': ex.id, 'station': ns, 'time_limit': ex.time_limit})


class AttemptHandler(JsonHandler):
    def initialize(self, checker: Checker, store: Store) -> None:
        self.checker, self.store = checker, store

    def _own(self, identity, person: str) -> None:
        if not allowed(identity, Action.SEE, Area.ATTEMPTS, person):
            raise tornado.web.HTTPError(403, 'another person\'s attempt')

    @authorized(Area.ATTEMPTS)
    async def get(self, attempt_id: str, stop: str | None = None) -> None:
        identity = self.identity
        live = self.checker.attempts.get(attempt_id)
        if live is not None:
            self._own(identity, _key(live.identity))
            self.finish({'live': True, 'attempt': attempt_id, 'exercise': live.exercise.id,
                         'outcome': live.evaluation.outcome()})
            return
        ended = self.checker.ended.get(attempt_id)
        rows = [ended.row()] if ended is not None else \
            await self.store.run(lambda c: results.select(c, attempt=attempt_id))
        if not rows:
            raise tornado.web.HTTPError(404, f'no attempt {attempt_id[:64]!r}')
        self._own(identity, rows[0]['person'])
        self.finish({'live': False, **rows[0]})

    @authorized(Area.ATTEMPTS)
    def post(self, attempt_id: str, stop: str | None = None) -> None:
        identity = self.identity
        live = self.checker.attempts.get(attempt_id)
        if live is None:
            raise tornado.web.HTTPError(404, f'no live attempt {attempt_id[:64]!r}')
        self._own(identity, _key(live.identity))
        self.finish({'live': False, **live.end('stopped').row()})


class ResultsHandler(JsonHandler):
    def initialize(self, store: Store) -> None:
        self.store = store

    @authorized(Area.ATTEMPTS)
    async def get(self) -> None:
        identity = self.identity
        person = self.get_query_argument('person', None)
        exercise = self.get_query_argument('exercise', None)
        if not allowed(identity, Action.MANAGE, Area.ATTEMPTS):
            if person is not None and person != _key(identity):
                raise tornado.web.HTTPError(403, 'another person\'s results: only an admin reads them')
            person = _key(identity)
        rows = await self.store.run(lambda c: results.select(c, person=person, exercise=exercise))
        summary = [{'person': p, 'exercise': e, 'name': v['last']['name'], 'attempts': v['attempts'],
                    'best': v['best'], 'last': v['last']}
                   for (p, e), v in results.best_and_last(rows).items()]
        if self.get_query_argument('summary', '') not in ('', '0'):   # the class view's look every 10 s
            self.finish({'summary': summary})
            return
        self.finish({'results': rows, 'summary': summary})


def exercise_routes(library: Library, checker: Checker, attempts: AttemptRule, store: Store) -> list:
    """``checker``: the live attempts (``exercises.Checker``); ``attempts``: the rule that says who may
    start one where (``Rules.attempts``); ``store``: where ended attempts' results are."""
    return [
        (r'/api/exercises/?', ExercisesHandler, {'library': library}),
        (r'/api/exercises/([A-Za-z0-9_-]+)/attempts/?', AttemptsHandler,
         {'library': library, 'checker': checker, 'attempts': attempts}),
        (r'/api/exercises/([A-Za-z0-9_-]+)', ExercisesHandler, {'library': library}),
        (r'/api/attempts/([0-9a-f]{1,64})(/stop)?', AttemptHandler, {'checker': checker, 'store': store}),
        (r'/api/exercise-results', ResultsHandler, {'store': store}),
    ]
