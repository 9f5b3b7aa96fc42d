"""The goal evaluator on messages built from the real ROS 2 Jazzy definitions (LaserScan, Odometry,
turtlesim/Pose), fed as the checker feeds it."""

from __future__ import annotations

import math

import pytest

from gateway.lab.goals import Evaluation, GoalError, build, topics_of
from protocol.convert import default_message
from protocol.msgdefs import Definitions

DEFS = Definitions.jazzy()
BOX = {'xmin': 7, 'xmax': 10, 'ymin': 7, 'ymax': 10}


def msg(type_: str, **fields) -> dict:
    m = default_message(DEFS, DEFS.msg(type_))
    m.update(fields)
    return m


def scan(*ranges, lo=0.1, hi=10.0) -> dict:
    return msg('sensor_msgs/msg/LaserScan', ranges=list(ranges), range_min=lo, range_max=hi)


def test_region_reached_from_turtlesim_pose_and_odometry():
    ev = Evaluation({'region': BOX})
    ev.pose(msg('turtlesim/msg/Pose', x=5.5, y=5.5))
    assert ev.outcome() is None
    assert ev.finish() == (False, 0.0)
    ev.pose(msg('turtlesim/msg/Pose', x=8.0, y=9.0))
    assert ev.outcome() is True
    ev.pose(msg('turtlesim/msg/Pose', x=1.0, y=1.0))      # left again: reached stays reached
    assert ev.finish() == (True, 1.0)
    odo = msg('nav_msgs/msg/Odometry')
    odo['pose']['pose']['position'].update(x=7.5, y=7.5)
    ev2 = Evaluation({'region': BOX})
    ev2.pose(odo)
    assert ev2.outcome() is True


def test_within_time():
    ev = Evaluation({'all': [{'region': BOX}, {'within': 5}]})
    ev.time(4.9)
    assert ev.outcome() is None
    ev.time(5.1)
    assert ev.outcome() is False
    ev.pose({'x': 8, 'y': 8})                             # too late
    assert ev.outcome() is False
    assert ev.finish() == (False, 0.5)


def test_clearance_with_laserscan():
    ev = Evaluation({'all': [{'region': BOX}, {'clearance': 0.5}]})
    ev.scan(scan(2.0, math.inf, 0.05, 1.2))               # 0.05 is under range_min: not a reading
    assert ev.outcome() is None
    ev.pose({'x': 8, 'y': 8})
    assert ev.outcome() is True
    ev2 = Evaluation({'clearance': 0.5})
    ev2.scan(scan(2.0, 0.4, 3.0))
    assert ev2.outcome() is False
    ev2.scan(scan(3.0))                                   # never closer than D: violated stays violated
    assert ev2.finish() == (False, 0.0)


def test_clearance_against_sim_walls_from_pose():
    ev = Evaluation({'clearance': 1.0})
    ev.pose({'x': 5.5, 'y': 5.5})
    assert ev.outcome() is True
    ev.pose({'x': 10.5, 'y': 5.5})                        # 0.59 from the east wall of turtlesim's world
    assert ev.outcome() is False
    small = Evaluation({'clearance': 1.0, 'walls': {'xmin': 0, 'xmax': 20, 'ymin': 0, 'ymax': 20}})
    small.pose({'x': 10.5, 'y': 5.5})
    assert small.outcome() is True


def test_topic_value():
    goal = {'topic': '/count', 'field': 'data', 'op': '>=', 'value': 3}
    ev = Evaluation(goal)
    assert topics_of(ev.root) == {'/count'}
    ev.topic('/count', msg('std_msgs/msg/Int32', data=2))
    ev.topic('/other', msg('std_msgs/msg/Int32', data=9))
    assert ev.outcome() is None
    ev.topic('/count', msg('std_msgs/msg/Int32', data=3))
    assert ev.finish() == (True, 1.0)
    nested = Evaluation({'topic': '/odom', 'field': 'pose.pose.position.x', 'op': '>', 'value': 1})
    odo = msg('nav_msgs/msg/Odometry')
    odo['pose']['pose']['position']['x'] = 1.5
    nested.topic('/odom', odo)
    assert nested.outcome() is True
    text = Evaluation({'topic': '/s', 'op': '<', 'value': 3})
    text.topic('/s', msg('std_msgs/msg/String', data='abc'))     # str < int: not a match, no error
    assert text.outcome() is None


def test_all_and_any():
    ev = Evaluation({'any': [{'region': BOX}, {'topic': '/done', 'value': True}]})
    ev.topic('/done', {'data': True})
    assert ev.outcome() is True
    both = Evaluation({'all': [{'region': BOX}, {'topic': '/done', 'value': True}, {'clearance': 0.2}]})
    both.pose({'x': 8, 'y': 8})
    assert both.outcome() is None
    assert both.finish() == (False, round(2 / 3, 4))
    nobody = Evaluation({'any': [{'within': 1}, {'clearance': 1}]})
    nobody.time(2)
    nobody.scan(scan(0.5))
    assert nobody.outcome() is False


@pytest.mark.parametrize('bad', [
    None, {}, [], {'region': {'xmin': 1}}, {'region': {'xmin': 3, 'xmax': 1, 'ymin': 0, 'ymax': 1}},
    {'within': -1}, {'within': True}, {'clearance': 'near'}, {'topic': 'count', 'value': 1},
    {'topic': '/c', 'op': 'is', 'value': 1}, {'topic': '/c'}, {'all': []}, {'eval': '1'},
    {'all': [{'all': [{'all': [{'all': [{'all': [{'all': [{'all': [{'all': [{'all': [{'within': 1}]}]}]}]}]}]}]}]}]},
])
def test_bad_goals_are_refused(bad):
    with pytest.raises(GoalError):
        build(bad)


def test_missed_says_which_parts_of_the_goal_were_not_met():
    ev = Evaluation({'all': [{'region': {'xmin': 7, 'xmax': 10, 'ymin': 7, 'ymax': 10}}, {'within': 20},
                             {'clearance': 0.5}, {'topic': '/count', 'op': '>=', 'value': 3}]})
    ev.pose({'x': 9, 'y': 0.3})           # 0.3 m from the bottom wall, not in the region
    ev.topic('/count', {'data': 3})
    ev.time(25)
    assert ev.missed() == ('region x 7..10, y 7..10 not reached; took 25.0 s, over the 20 s allowed; '
                           'came within 0.30 m of a wall (0.5 m of clearance asked)')
    either = Evaluation({'any': [{'region': BOX}, {'topic': '/done', 'value': True}]})
    assert either.missed().startswith('none of: region x ') and either.missed().endswith('/done data == True not reached')
    either.topic('/done', {'data': True})
    assert either.missed() == ''
