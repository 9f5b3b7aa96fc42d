"""Exercises the gateway checks: a start program, a station kind, a time limit and a goal as data.

An exercise is a JSON file ``ID.json`` in ``--exercises-dir`` (an admin's POST /api/exercises
writes one there too)::

    {"title": "Reach the corner", "titles": {"es": "Llega a la esquina", "de": "Erreiche die Ecke"},
     "instructions": "Drive the turtle to the **top right** corner ..." or {"en": "...", "es": "..."},
     "station_kind": "turtlesim", "time_limit": 60,
     "start": {"blocks": {...}} or {"text": "..."},
     "pose_topic": "pose", "scan_topic": "scan",
     "goal": {"all": [{"region": {"xmin": 8, "xmax": 11, "ymin": 8, "ymax": 11}}, {"within": 45}]},
     "allow_services": ["turtle1/set_pen"], "refuse_services": ["turtle1/rotate_absolute"]}

During an attempt the station's services that move the robot without driving it (teleport, reset,
spawn, kill: ``rules.stationnames.MOVERS``) are refused to everyone, and so are those the exercise
names in ``refuse_services``; ``allow_services`` lets some through (names relative to the station,
or globs).

The title and the instructions (Markdown, shown beside the editor: the IDE renders it with no HTML
of its own) are a text or one per language (``{"en": ..., "es": ...}``; ``title`` may be such an
object too, or ``titles`` gives the other languages): the pages show the reader's.
``goals`` turns the goal into an evaluator (pure); ``checker`` watches the robot's own topics during
an attempt and keeps each result (``results``: table ``exercise_attempts``), then tells the hooks
(``on_attempt_ended``). Files are read on each request (a class has tens), so an edit needs no restart.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

from .checker import AttemptResult, Checker, Exercise, attempt_person
from .goals import GoalError, build

__all__ = ['AttemptResult', 'Checker', 'Exercise', 'ExerciseError', 'Library', 'attempt_person', 'parse']

ID = re.compile(r'^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$')
TOPIC = re.compile(r'^/?[A-Za-z_][A-Za-z0-9_/]{0,200}$')
LANG = re.compile(r'^[A-Za-z]{2,3}([-_][A-Za-z0-9]{1,8}){0,3}$')
SERVICE = re.compile(r'^/?[A-Za-z_*?][A-Za-z0-9_/*?]{0,200}$')
MAX_FILE = 256 * 1024
MAX_INSTRUCTIONS = 64 * 1024
MAX_TIME = 3600.0


class ExerciseError(ValueError):
    """The exercise's data is wrong; the message says which part."""


def parse(ex_id: str, data) -> Exercise:
    if not ID.match(ex_id or ''):
        raise ExerciseError('an exercise id is letters, digits, _ and - (64 at most)')
    if not isinstance(data, dict):
        raise ExerciseError(f'{ex_id}: not a JSON object')
    limit = data.get('time_limit', 60)
    if isinstance(limit, bool) or not isinstance(limit, (int, float)) or not (0 < limit <= MAX_TIME) \
            or not math.isfinite(limit):
        raise ExerciseError(f'{ex_id}: time_limit is seconds, above 0 and at most {MAX_TIME:g}')
    try:
        build(data.get('goal'))
    except GoalError as e:
        raise ExerciseError(f'{ex_id}: goal: {e}') from None
    start = data.get('start', {})
    if not isinstance(start, dict) or not set(start) <= {'blocks', 'text'}:
        raise ExerciseError(f'{ex_id}: start is {{"blocks": ...}} or {{"text": "..."}}')
    topics = {}
    for key, default in (('pose_topic', 'pose'), ('scan_topic', '')):
        value = data.get(key, default)
        if not isinstance(value, str) or (value and not TOPIC.match(value)):
            raise ExerciseError(f'{ex_id}: {key} is a topic name')
        topics[key] = value
    services = {}
    for key in ('allow_services', 'refuse_services'):
        value = data.get(key, [])
        if not isinstance(value, list) or len(value) > 64 or not all(isinstance(v, str) and SERVICE.match(v) for v in value):
            raise ExerciseError(f'{ex_id}: {key} is a list of service names or globs (64 at most)')
        services[key] = tuple(value)
    title, kind = data.get('title', ex_id), data.get('station_kind', '')
    if not isinstance(kind, str):
        raise ExerciseError(f'{ex_id}: station_kind is text')
    if not isinstance(data.get('titles', {}), dict):
        raise ExerciseError(f'{ex_id}: titles is an object of language -> title')
    titles = _texts(ex_id, 'titles', data.get('titles', {}), 200, empty=True)
    if isinstance(title, dict):
        titles = {**_texts(ex_id, 'title', title, 200), **titles}
        title = titles.get('en') or next(iter(titles.values()))
    elif not isinstance(title, str):
        raise ExerciseError(f'{ex_id}: title is a text, or an object of language -> text')
    instructions = _texts(ex_id, 'instructions', data.get('instructions', ''), MAX_INSTRUCTIONS, empty=True)
    return Exercise(id=ex_id, title=title[:200], goal=data['goal'], time_limit=float(limit),
                    station_kind=kind[:100], start=start, titles=titles, instructions=instructions, **topics,
                    **services)


def _texts(ex_id: str, key: str, value, limit: int, empty: bool = False):
    """A text or {language: text}, as given and checked (each text cut at ``limit``)."""
    if isinstance(value, str):
        return value[:limit]
    if isinstance(value, dict) and (value or empty) and all(
            isinstance(k, str) and LANG.match(k) and isinstance(v, str) for k, v in value.items()):
        return {k: v[:limit] for k, v in value.items()}
    raise ExerciseError(f'{ex_id}: {key} is a text, or an object of language -> text '
                        '({"en": "...", "es": "..."})')


def public(ex: Exercise) -> dict:
    return {'id': ex.id, 'title': ex.title, 'titles': ex.titles, 'instructions': ex.instructions,
            'station_kind': ex.station_kind, 'time_limit': ex.time_limit,
            'start': ex.start, 'goal': ex.goal, 'pose_topic': ex.pose_topic, 'scan_topic': ex.scan_topic,
            'allow_services': list(ex.allow_services), 'refuse_services': list(ex.refuse_services)}


class Library:
    """The exercises of one folder."""

    def __init__(self, folder: Path | None):
        self.folder = Path(folder).expanduser() if folder else None

    def get(self, ex_id: str) -> Exercise | None:
        if self.folder is None or not ID.match(ex_id or ''):
            return None
        path = self.folder / f'{ex_id}.json'
        try:
            text = path.read_bytes()[:MAX_FILE + 1]
        except OSError:
            return None
        if len(text) > MAX_FILE:
            raise ExerciseError(f'{path.name}: larger than {MAX_FILE} bytes')
        try:
            return parse(ex_id, json.loads(text))
        except (ValueError, RecursionError) as e:
            raise ExerciseError(f'{path.name}: {e}') from None

    def all(self) -> tuple[list[Exercise], list[str]]:
        """(the exercises, what is wrong with the files that are not)."""
        found, problems = [], []
        if self.folder is None or not self.folder.is_dir():
            return found, problems
        for path in sorted(self.folder.glob('*.json')):
            try:
                ex = self.get(path.stem)
            except ExerciseError as e:
                problems.append(str(e))
                continue
            if ex is not None:
                found.append(ex)
        return found, problems

    def save(self, ex_id: str, data: dict) -> Exercise:
        ex = parse(ex_id, data)
        if self.folder is None:
            raise ExerciseError('no --exercises-dir to keep exercises in')
        self.folder.mkdir(parents=True, exist_ok=True)
        tmp = self.folder / f'.{ex_id}.json.tmp'
        tmp.write_text(json.dumps({k: v for k, v in public(ex).items() if k != 'id'}, indent=1))
        tmp.replace(self.folder / f'{ex_id}.json')
        return ex
