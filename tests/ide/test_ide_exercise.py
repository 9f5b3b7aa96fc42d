"""An exercise in the IDE, in Chromium: ?exercise=ID loads its start program; "Start attempt" runs
it on the page's station and the gateway (watching /turtle1/pose itself) passes it at the goal; a
program stopped before its goal ends the attempt as not passed. Read back through the API."""

from __future__ import annotations

import json

import pytest

from tests.support.http import api
from tests.support.ide import drive, program

EAST = {'title': 'East', 'time_limit': 30, 'pose_topic': 'turtle1/pose',
        'start': {'blocks': program(drive(seconds=20, speed=2.0), name='east')},
        'goal': {'region': {'xmin': 7, 'xmax': 11.1, 'ymin': 0, 'ymax': 11.1}}}
FAR = {'title': 'Far', 'time_limit': 30, 'pose_topic': 'turtle1/pose',
       'start': {'blocks': program(drive(seconds=20, speed=0.1), name='far')},
       'goal': {'region': {'xmin': 0, 'xmax': 0.3, 'ymin': 0, 'ymax': 0.3}}}


@pytest.fixture(scope='module')
def gw(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('exercises')
    (folder / 'east.json').write_text(json.dumps(EAST))
    (folder / 'far.json').write_text(json.dumps(FAR))
    return start_gateway('--robot', 'turtlesim', '--exercises-dir', str(folder))


def started(gw, ide_factory, exercise: str):
    """The IDE opened on ``exercise`` (its start program loaded, connected) and its attempt started:
    (the page, the attempt's id)."""
    ide = ide_factory(gw, gw.http_url + f'?exercise={exercise}')
    ide.page.wait_for_function("(name) => rosgateIde.programName === name", arg=exercise)
    ide.page.wait_for_selector('#exercise-start:not([disabled])')
    ide.page.wait_for_function("document.body.dataset.connection === 'connected'")
    ide.page.click('#exercise-start')
    ide.page.wait_for_function('rosgateIde.exercise?.attempt')
    return ide, ide.page.evaluate('rosgateIde.exercise.attempt')


def test_the_goal_reached_from_the_ide_passes(gw, ide_factory):
    ide, attempt = started(gw, ide_factory, 'east')
    ide.page.wait_for_function("document.body.dataset.attempt === 'passed'", timeout=20000)
    ide.page.click('#stop')
    status, result = api(gw, 'GET', f'/api/attempts/{attempt}')
    assert status == 200 and result['passed'] is True and result['score'] == 1.0 and result['why'] == 'goal'
    assert json.loads(result['program'])['name'] == 'east'
    assert 'passed' in ide.page.inner_text('#exercise-status')


def test_a_program_stopped_before_its_goal_fails(gw, ide_factory):
    ide, attempt = started(gw, ide_factory, 'far')
    ide.page.wait_for_function("rosgateIde.runner.state === 'running'")
    ide.page.click('#stop')
    ide.page.wait_for_function("document.body.dataset.attempt === 'failed'", timeout=15000)
    status, result = api(gw, 'GET', f'/api/attempts/{attempt}')
    assert status == 200 and result['passed'] is False and result['why'] == 'stopped'
