"""A live attempt: the goal checked on the robot's own topics while the student's program runs.

The checker watches the topic's shared fan-out (as a ``/stream`` camera source does: one backend
subscription for all), so it reads what the backend delivers (turtlesim's ``/turtleN/pose``, a rover's ``odom``, its
``scan``) and never what a page says. An attempt ends at the goal reached (or failed for good), at
the exercise's time limit, or when the program stops (``stop``); its result is written to the store
and told as the hooks' ``on_attempt_ended(identity, exercise, attempt_result)`` (``rules.hooks``):
the grades' outbox hears it. With a ``recorder`` (the gateway's recordings), each attempt records the robot's
pose (and scan, and the topics of its goal) and the station's velocity commands, owned by the
student: the teacher's replay of the run. While an attempt is live (``live()``), its station is
kept for it by ``rules.attempts``: the pose and scan it reads (``Attempt.kept``) are the robot's
alone (on the sim a client's /turtle1/pose reached the fan-out as the robot's own, and passed a goal
never reached), its station is the attempter's, and no service moves the robot without driving it
(the exercise's ``allow_services`` excepted, its ``refuse_services`` besides). A ``topic`` goal's
topic stays open: it may be what the program publishes.
"""

from __future__ import annotations

import asyncio
import hashlib
import logging
import secrets
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol

from . import results
from .goals import Evaluation, topics_of

log = logging.getLogger('rosgate.exercises')
RECENT = 256   # ended attempts answered from memory: a poll right after the end finds it before the store does
POSE_TYPES = frozenset({'turtlesim/msg/Pose', 'geometry_msgs/msg/Pose', 'geometry_msgs/msg/PoseStamped',
                        'nav_msgs/msg/Odometry'})


# --- what the checker is given (its doors): the robot's topics, a recorder, the store --------------

class Watched(Protocol):
    """One topic's shared fan-out (bridge.fanout.TopicFanout): watched under a key, left by it."""
    def watch(self, key: object, callback: Callable[[dict, Any], None]) -> None: ...
    def unwatch(self, key: object) -> None: ...


class Graph(Protocol):
    """The robot graph's listings (a backend)."""
    def topics(self) -> list[tuple[str, str]]: ...
    def publishers(self, topic: str) -> list: ...


class Topics(Protocol):
    """The robot's topics as the checker reads them (bridge.gateway.Gateway is one)."""
    backend: Graph
    def topic_type(self, topic: str) -> str | None: ...
    def fanout(self, topic: str, type: str) -> Watched: ...


class Recorder(Protocol):
    """The recordings (media.recordings.RecordingManager): an attempt's replay."""
    def start(self, globs: tuple[str, ...], max_seconds: float | None, owner: str | None, *, counted: bool,
              who: Any, attempt: str) -> Any: ...
    def stop(self, recording: Any, reason: str) -> None: ...


class Submits(Protocol):
    """The store's one writer (store.Store): fn(connection) run on its thread."""
    def submit(self, fn: Callable) -> Any: ...


class LiveAttempts(dict):
    """The attempts going now, by id: the checker's, read by ``rules.attempts`` (their stations kept)."""

    def live(self) -> Iterable['Attempt']:
        return self.values()


@dataclass(frozen=True)
class Exercise:
    id: str
    title: str
    goal: dict
    time_limit: float
    station_kind: str = ''
    start: dict = field(default_factory=dict)    # {"blocks": ...} or {"text": ...}
    pose_topic: str = 'pose'                     # relative to the station's namespace
    scan_topic: str = ''
    titles: dict = field(default_factory=dict)   # the title in other languages: {lang: text}
    instructions: str | dict = ''                # Markdown, or {lang: Markdown}
    allow_services: tuple = ()                   # the station's services it allows that move the robot
    refuse_services: tuple = ()                  # and those it refuses besides (names or globs)


@dataclass(frozen=True)
class AttemptResult:
    attempt: str
    exercise: str
    person: str
    name: str
    station: str
    passed: bool
    score: float
    why: str
    started_at: float
    ended_at: float
    program: str
    recording: str | None = None
    missed: str = ''      # the goal's parts not met, in words (the gradebook's comment; not kept in the store)

    def row(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != 'missed'}


def attempt_person(identity, browser: str | None = None, name: str = '') -> tuple[str, str]:
    """(key, name) of whoever makes an attempt: a signed-in person (an LTI identity's key, a token's
    name), else a browser without sign-in (``browser``: its id from the pages' cookie, kept here only
    as a digest, since the id is what holds a station; ``name`` as the page gives it), else anyone."""
    if identity is not None:
        return identity.key or identity.name, identity.name
    if browser:
        digest = hashlib.sha256(browser.encode()).hexdigest()[:16]
        return f'browser-{digest}', (name.strip()[:60] or f'browser {digest[:6]}')
    return 'anyone', 'anyone'


class Attempt:
    def __init__(self, checker: 'Checker', exercise: Exercise, identity, station: str, program: str,
                 person: str | None = None, who: tuple[str, str] | None = None):
        self.checker, self.exercise, self.identity, self.station = checker, exercise, identity, station
        self.person = person or ''                   # whose station it is while it is live (rules.attempts)
        self.key, self.name = who or attempt_person(identity)   # whose result it is (key, name)
        self.kept: frozenset[str] = frozenset()     # the pose and scan topics it reads
        self.allow = tuple(checker.topic(station, n) for n in exercise.allow_services)
        self.refuse = tuple(checker.topic(station, n) for n in exercise.refuse_services)
        self.id = secrets.token_hex(8)
        self.program = program[:results.MAX_PROGRAM]
        self.evaluation = Evaluation(exercise.goal)
        self.started = time.time()
        self.taps: list = []
        self.recording = None
        self.result: AttemptResult | None = None
        self.done = asyncio.get_running_loop().create_future()
        self.timer = asyncio.get_running_loop().call_later(exercise.time_limit, self.end, 'time')

    def feed(self, kind: str, topic: str, msg: dict) -> None:
        """One message of a watched topic (on the fan-out's hot path: never raises into it)."""
        try:
            self._feed(kind, topic, msg)
        except Exception:
            log.exception('attempt %s cannot take a message of %s', self.id, topic)

    def _feed(self, kind: str, topic: str, msg: dict) -> None:
        if self.result is not None:
            return
        ev = self.evaluation
        ev.time(time.time() - self.started)
        getattr(ev, kind)(*((topic, msg) if kind == 'topic' else (msg,)))
        outcome = ev.outcome()
        if outcome is True:
            self.end('goal')
        elif outcome is False:
            self.end('failed')

    def end(self, why: str) -> AttemptResult | None:
        if self.result is not None:
            return self.result
        self.timer.cancel()
        recording = self.checker.stop_recording(self)
        self.evaluation.time(time.time() - self.started)
        passed, score = self.evaluation.finish()
        self.result = AttemptResult(
            attempt=self.id, exercise=self.exercise.id, person=self.key, name=self.name, station=self.station,
            passed=passed, score=score, why=why, started_at=self.started, ended_at=time.time(),
            program=self.program, recording=recording, missed='' if passed else self.evaluation.missed())
        self.checker.finished(self)
        if not self.done.done():
            self.done.set_result(self.result)
        return self.result


class AttemptEvents(Protocol):
    """Where an attempt's end is told (``rules.hooks.Hooks``: ``on_attempt_ended`` of every part)."""
    def attempt_ended(self, identity, exercise, result) -> None: ...


class Checker:
    """The live attempts (one per station at a time); each one's end told to ``events``
    (``rules.hooks.Hooks``: ``on_attempt_ended``, heard by the grades' outbox)."""

    def __init__(self, topics: Topics, store: Submits, *, attempts: LiveAttempts | None = None,
                 recorder: Recorder | None = None, events: AttemptEvents | None = None):
        self.topics, self.store, self.recorder, self.events = topics, store, recorder, events
        self.attempts = LiveAttempts() if attempts is None else attempts   # attempt id -> Attempt
        self.ended: OrderedDict[str, AttemptResult] = OrderedDict()   # the newest, while the store writes

    def topic(self, station: str, name: str) -> str:
        """A relative name under the station's namespace ('' is the root: ``turtle1/pose`` -> ``/turtle1/pose``)."""
        if name.startswith('/'):
            return name
        ns = station.strip('/')
        return f'/{ns}/{name}' if ns else f'/{name}'

    def pose_topic(self, station: str, name: str) -> str:
        """The station's pose topic: the exercise's name under the station, or where the robot has no
        such topic, its one published pose-like topic (turtlesim's ``turtle1/pose``, a rover's ``odom``):
        an exercise left at the default ``pose`` works on a single turtle or rover too."""
        topic = self.topic(station, name)
        if name.startswith('/') or self.topics.topic_type(topic) is not None:
            return topic
        under = f'/{station.strip("/")}/' if station.strip('/') else '/'
        graph = self.topics.backend
        found = [t for t, type_ in graph.topics() if t.startswith(under) and type_ in POSE_TYPES
                 and graph.publishers(t)]
        return found[0] if len(found) == 1 else topic

    def start(self, exercise: Exercise, identity, station: str, program: str, person: str | None = None,
              who: tuple[str, str] | None = None) -> Attempt:
        """A new attempt on ``station`` (rules.attempts has let it start), the station held for
        ``person`` while it is live, its result ``who``'s ((key, name): ``attempt_person``; the identity's by
        default): the one live there ends as stopped."""
        for live in self.attempts.values():
            if live.station == station:
                live.end('stopped')
                break
        attempt = Attempt(self, exercise, identity, station, program, person, who)
        watch = [(self.pose_topic(station, exercise.pose_topic), 'pose')]
        if exercise.scan_topic:
            watch.append((self.topic(station, exercise.scan_topic), 'scan'))
        attempt.kept = frozenset(t for t, _ in watch)
        watch += [(t, 'topic') for t in sorted(topics_of(attempt.evaluation.root))]
        self.attempts[attempt.id] = attempt
        try:
            for topic, kind in watch:
                self._tap(attempt, topic, kind)
        except Exception:
            attempt.end('failed')
            raise
        self._record(attempt, [t for t, _ in watch] + [self.topic(station, '*cmd_vel')])
        return attempt

    def _record(self, attempt: Attempt, globs: list[str]) -> None:
        if self.recorder is None:
            return
        who = attempt.identity
        try:
            attempt.recording = self.recorder.start(tuple(globs), attempt.exercise.time_limit + 1,
                                                    who.owner if who else None, counted=False, who=who,
                                                    attempt=attempt.id)
        except Exception as e:   # a full disk: the attempt is checked all the same, without its replay
            log.warning('attempt %s is not recorded: %s', attempt.id, e)

    def stop_recording(self, attempt: Attempt) -> str | None:
        """Ends the attempt's recording; its id (None: not recorded)."""
        rec, attempt.recording = attempt.recording, None
        if rec is None:
            return None
        self.recorder.stop(rec, f'attempt {attempt.id} ended')
        return rec.id if rec.state == 'done' else None

    def live(self):
        """The attempts going now (rules.attempts keeps their stations)."""
        return self.attempts.values()

    def _tap(self, attempt: Attempt, topic: str, kind: str) -> None:
        type_ = self.topics.topic_type(topic)
        if type_ is None:
            raise LookupError(f'{topic} is not published: the station has no such topic')
        fan = self.topics.fanout(topic, type_)
        key = ('exercise', attempt.id, kind)
        fan.watch(key, lambda msg, _image: attempt.feed(kind, topic, msg))
        attempt.taps.append((fan, key))

    def stop_all(self) -> None:
        """The gateway is stopping: every live attempt ends as stopped (and is kept)."""
        for attempt in list(self.attempts.values()):
            attempt.end('stopped')

    def finished(self, attempt: Attempt) -> None:
        self.attempts.pop(attempt.id, None)
        for fan, key in attempt.taps:
            try:
                fan.unwatch(key)
            except Exception:
                log.exception('cannot leave %s', fan.topic)
        attempt.taps.clear()
        self.ended[attempt.id] = attempt.result
        while len(self.ended) > RECENT:
            self.ended.popitem(last=False)
        row = attempt.result.row()
        self.store.submit(lambda conn: results.insert(conn, row))
        if self.events is not None:
            self.events.attempt_ended(attempt.identity, attempt.exercise, attempt.result)
