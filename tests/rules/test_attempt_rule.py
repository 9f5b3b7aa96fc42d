"""rules.attempts as a table, in-process, its clock an argument: who may call, publish and start
what while an exercise attempt is live (from outside: tests/security/test_class_doors.py)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from gateway.rules.attempts import AttemptCaps, AttemptRefused, AttemptRule
from gateway.rules.policy import GATEWAY_ROLE
from protocol.errors import ProtocolError


def who(person: str, role: str = 'operator'):
    return SimpleNamespace(attrs={'person': person, 'role': role, 'name': person.split()[-1]}, id=1)


ADA, BO, TEACHER = who('user ada'), who('user bo'), who('user teacher', 'admin')
LIVE = SimpleNamespace(station='/s01', person='user ada', name='ada', kept=frozenset({'/s01/turtle1/pose'}),
                       allow=('/s01/turtle1/teleport_absolute',), refuse=('/s01/turtle1/rotate_*',))


@pytest.mark.parametrize('asker, action, name, refused', [
    (ADA, 'call', '/s01/turtle1/teleport_relative', 'moves the robot'),   # a mover, to everyone
    (TEACHER, 'call', '/s01/reset', 'moves the robot'),
    (BO, 'call', '/s01/kill', 'moves the robot'),
    (ADA, 'call', '/s01/turtle1/teleport_absolute', None),                # the exercise allows it
    (ADA, 'send_goal', '/s01/turtle1/rotate_absolute', 'moves the robot'),  # and refuses this one
    (ADA, 'call', '/s01/turtle1/set_pen', None),                          # hers
    (BO, 'call', '/s01/turtle1/set_pen', "ada's live exercise attempt"),  # not his
    (TEACHER, 'call', '/s01/turtle1/set_pen', None),
    (BO, 'call', '/s02/reset', None),                                     # another station
    (BO, 'subscribe', '/s01/turtle1/pose', None),                         # watching stays open
])
def test_calls_during_an_attempt(asker, action, name, refused):
    why = AttemptRule(lambda: [LIVE]).keeper(asker, action, name)
    assert (why is None) if refused is None else (why is not None and refused in why), why


def pub(topic: str):
    return SimpleNamespace(topic=topic, type='std_msgs/msg/String')


def test_publishing_during_an_attempt():
    rule = AttemptRule(lambda: [LIVE])
    for sender in (ADA, TEACHER):                     # the pose is the robot's alone
        with pytest.raises(ProtocolError, match='read by a live exercise attempt'):
            rule.publish_hook(sender, pub('/s01/turtle1/pose'), {})
    with pytest.raises(ProtocolError, match="ada's live exercise attempt"):
        rule.publish_hook(BO, pub('/s01/turtle1/cmd_vel'), {})
    assert rule.publish_hook(ADA, pub('/s01/turtle1/cmd_vel'), {'x': 1}) == {'x': 1}
    assert rule.publish_hook(TEACHER, pub('/s01/turtle1/cmd_vel'), {'x': 1}) == {'x': 1}
    itself = SimpleNamespace(attrs={'role': GATEWAY_ROLE}, id=-1)
    assert rule.publish_hook(itself, pub('/s01/turtle1/pose'), {'x': 0}) == {'x': 0}   # the gateway's own stop


def test_starts_are_capped_per_person_and_not_over_another_persons_attempt():
    now = [1000.0]
    rule = AttemptRule(lambda: [LIVE], caps=AttemptCaps(per_minute=3, per_day=5), clock=lambda: now[0])
    with pytest.raises(AttemptRefused) as over:
        rule.start_refusal(BO, 'user bo', '/s01')
    assert over.value.status == 409 and 'ada' in over.value.message
    for _ in range(3):
        rule.start_refusal(BO, 'user bo', '/s02')
        rule.started('user bo')
    with pytest.raises(AttemptRefused) as fast:
        rule.start_refusal(BO, 'user bo', '/s02')
    assert fast.value.status == 429 and 'in the last minute' in fast.value.message and 'try again in 60 s' in fast.value.message
    now[0] += 61
    for _ in range(2):
        rule.start_refusal(BO, 'user bo', '/s02')
        rule.started('user bo')
    now[0] += 61
    with pytest.raises(AttemptRefused) as day:
        rule.start_refusal(BO, 'user bo', '/s02')
    assert day.value.status == 429 and 'today' in day.value.message
    rule.start_refusal(TEACHER, 'user teacher', '/s02')      # an admin is not counted
    now[0] += 86400
    rule.start_refusal(BO, 'user bo', '/s02')                # a day later: again
