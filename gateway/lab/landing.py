"""Where an LMS launch lands, and what a teacher's deep-linking pick adds to the course.

``landing_of(claims)``: the page a launch opens (its custom ``page``, ``station``, ``program``,
``exercise``, ``mode``/``lang``, else the path of its target link; the course's language as
``?lang=``). ``deep_link_item(pick, ...)``: the LtiResourceLink a teacher's pick becomes (an exercise
with its AGS ``lineItem``, an example, a page; the IDE's text mode; a station), or a ``Refusal`` of
400 naming what is wrong. The launch itself and the picker's page are ``web.lti``.
"""

from __future__ import annotations

import re
from urllib.parse import urlencode, urlsplit

from ..auth import lti
from ..rules.errors import Refusal
from . import grades
from .exercises import ID as EXERCISE_ID, ExerciseError

TEXT_LANGS = ('python', 'javascript')   # the IDE's text programs
LOCALE = re.compile(r'[A-Za-z]{2,3}([-_][A-Za-z0-9]{1,8}){0,3}')   # a BCP 47 tag, as LMSs send it
PAGES = {'ide': '/', '/': '/', 'teleop': '/teleop', '/teleop': '/teleop', 'class': '/class', '/class': '/class'}


def landing_of(claims: dict) -> str:
    """Where a launch lands: custom parameters page, station, program; else the path of
    target_link_uri when it is one of the pages; else the IDE. The course's language
    (launch_presentation.locale) comes along as ?lang= (as ?locale= for a text exercise, whose ?lang= is the program's),
    which the page's words follow."""
    custom = claims.get(lti.CLAIM + 'custom') or {}
    page = PAGES.get(str(custom.get('page', '')).strip().lower())
    if page is None:
        path = urlsplit(str(claims.get(lti.CLAIM + 'target_link_uri', ''))).path.rstrip('/') or '/'
        page = PAGES.get(path, '/')
    query = {}
    station = str(custom.get('station', '')).strip().strip('/')
    if station and station.replace('_', '').isalnum():
        query['ns'] = '/' + station
    program = str(custom.get('program', '')).strip()
    if program and page == '/':
        query['program'] = program[:64]
    exercise = grades.exercise_of(claims) or ''
    if exercise and page == '/' and EXERCISE_ID.fullmatch(exercise):
        query['exercise'] = exercise
    presentation = claims.get(lti.CLAIM + 'launch_presentation')
    locale = str(presentation.get('locale', '')) if isinstance(presentation, dict) else ''
    lang = str(custom.get('lang', '')).strip().lower()
    if page == '/' and str(custom.get('mode', '')).strip().lower() == 'text' and lang in TEXT_LANGS:
        query['mode'], query['lang'] = 'text', lang     # a text exercise (ide/js/editors/textmode.js)
        if LOCALE.fullmatch(locale):
            query['locale'] = locale                    # ?lang= is the program's language here
    elif LOCALE.fullmatch(locale):
        query['lang'] = locale
    return page + ('?' + urlencode(query, safe='/:') if query else '')


def deep_link_item(pick: str, as_text: str, station: str, title: str, exercises, base: str) -> dict:
    """The resource link a deep linking pick adds (``exercises``: the ``Library``, None without
    --exercises-dir; ``base``: this gateway as the browser reaches it)."""
    custom, line_item = {}, None
    if pick.startswith('exercise:'):
        try:
            ex = exercises.get(pick.split(':', 1)[1]) if exercises is not None else None
        except ExerciseError as e:
            raise Refusal(400, str(e)) from None
        if ex is None:
            raise Refusal(400, f'no exercise {pick.split(":", 1)[1][:64]!r} in --exercises-dir')
        page, custom['exercise'] = '/', ex.id
        line_item = {'scoreMaximum': 1, 'label': ex.title, 'resourceId': ex.id}
    elif pick.startswith('example:'):
        page, custom['program'] = '/', 'example:' + pick.split(':', 1)[1][:64]
    else:
        page = PAGES.get(pick, '/')
    if page == '/' and as_text in TEXT_LANGS:
        custom['mode'], custom['lang'] = 'text', as_text
    station = station.strip().strip('/')
    if station:
        if not station.replace('_', '').isalnum():
            raise Refusal(400, f'a station is a name like s03, not {station[:40]!r}')
        custom['station'] = station
    title = title.strip()[:200]
    if line_item is not None and title in ('', 'Robot lab'):
        title = line_item['label']          # the gradebook column and the link read the same
    item = {'type': 'ltiResourceLink', 'title': title or 'Robot lab',
            'url': base + page + (f'?exercise={custom["exercise"]}' if line_item is not None else '')}
    if custom:
        item['custom'] = custom
    if line_item is not None:   # the platform makes the gradebook column (AGS) the attempts' scores go to
        item['lineItem'] = line_item
    return item
