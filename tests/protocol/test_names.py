"""ROS 2 names as rcl checks them (protocol/names.py), a pure function: the sim refuses what rcl
refuses (tests/security/test_class_doors.py tries them over the websocket)."""

from __future__ import annotations

import pytest

from protocol.names import MAX_LENGTH, name_problem


@pytest.mark.parametrize('name', ['/chatter', '/s01/turtle1/cmd_vel', '/_private/x', '/a1/b_2', '/fibonacci/_action/status',
                                  '/' + 'x' * (MAX_LENGTH - 1), '/rosgate/runs/r0a1b2c3d/output'])
def test_names_rcl_takes(name):
    assert name_problem(name) is None


@pytest.mark.parametrize('name, why', [
    ('', 'empty'), ('chatter', 'starts with /'), ('/a/', 'end with /'), ('/a b', "' '"), ('/a\nb', "'\\n'"),
    ('/a<b>', "'<'"), ('/\u202egnp', "'\\u202e'"), ('/ümlaut', "'ü'"), ('/a//b', '//'), ('/a/1b', 'digit'),
    ('/1a', 'digit'), ('/a-b', "'-'"), ('/a.b', "'.'"), ('/~/a', "'~'"), ('/{node}/a', "'{'"),
    ('/' + 'x' * MAX_LENGTH, 'at most')])
def test_names_rcl_refuses(name, why):
    problem = name_problem(name)
    assert problem is not None and why in problem, problem
