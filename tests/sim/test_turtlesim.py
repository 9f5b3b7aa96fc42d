"""The turtlesim work-alike, black-box through the websocket, against ROS 2 Jazzy turtlesim."""

from __future__ import annotations

import math
import time

import pytest
import roslibpy

from tests.support.fixtures import client_of
from tests.support.ros import Inbox, call, cancelled, client, stream, twist
from tests.support.wait import wait_for

SIZE = 11.088889
CENTRE = 5.544445
UNPAINTED = {'r': 255, 'g': 255, 'b': 255}   # the real node's path image is transparent white

# What `ros2 topic/service/action list -t` shows for a fresh Jazzy turtlesim_node
# (the node's parameter services and /parameter_events aside).
REAL_TOPICS = {
    '/turtle1/cmd_vel': 'geometry_msgs/msg/Twist',
    '/turtle1/pose': 'turtlesim/msg/Pose',
    '/turtle1/color_sensor': 'turtlesim/msg/Color',
    '/rosout': 'rcl_interfaces/msg/Log',
}
REAL_SERVICES = {
    '/clear': 'std_srvs/srv/Empty',
    '/kill': 'turtlesim/srv/Kill',
    '/reset': 'std_srvs/srv/Empty',
    '/spawn': 'turtlesim/srv/Spawn',
    '/turtle1/set_pen': 'turtlesim/srv/SetPen',
    '/turtle1/teleport_absolute': 'turtlesim/srv/TeleportAbsolute',
    '/turtle1/teleport_relative': 'turtlesim/srv/TeleportRelative',
}
REAL_ACTIONS = {'/turtle1/rotate_absolute': 'turtlesim/action/RotateAbsolute'}


ros = client_of('turtle_gw', 'module')


@pytest.fixture
def fresh(ros):
    """Start each test from a reset turtlesim."""
    call(ros, '/reset', 'std_srvs/srv/Empty')
    return ros


def spawn(ros, name: str, x: float, y: float, theta: float = 0.0) -> str:
    return call(ros, '/spawn', 'turtlesim/srv/Spawn', {'x': x, 'y': y, 'theta': theta, 'name': name})['name']


def rosapi(ros, service: str, type: str, **request) -> dict:
    return call(ros, f'/rosapi/{service}', f'rosapi_msgs/srv/{type}', request)


def test_interfaces_match_real_turtlesim(fresh):
    ros = fresh
    topics = dict(zip(*rosapi(ros, 'topics', 'Topics').values()))
    for name, type in REAL_TOPICS.items():
        assert topics.get(name) == type, name
        assert ros.get_topic_type(name) == type
    services = ros.get_services()
    for name, type in REAL_SERVICES.items():
        assert name in services
        assert ros.get_service_type(name) == type
    servers = rosapi(ros, 'action_servers', 'GetActionServers')['action_servers']
    for name, type in REAL_ACTIONS.items():
        assert name in servers
        assert rosapi(ros, 'action_type', 'ActionType', action=name)['type'] == type
    assert '/turtlesim' in ros.get_nodes()
    details = ros.get_node_details('/turtlesim')
    assert '/turtle1/pose' in details['publishing'] and '/turtle1/cmd_vel' in details['subscribing']
    assert {'/spawn', '/turtle1/set_pen'} <= set(details['services'])
    pose = ros.get_message_details('turtlesim/msg/Pose')['typedefs'][0]
    assert pose['fieldnames'] == ['x', 'y', 'theta', 'linear_velocity', 'angular_velocity']
    assert pose['fieldtypes'] == ['float32'] * 5
    params = ros.get_params()
    assert {'/turtlesim:background_r', '/turtlesim:background_g', '/turtlesim:background_b'} <= set(params)


def test_starts_at_the_centre_and_publishes_pose_every_16_ms(fresh):
    with Inbox(fresh, '/turtle1/pose', 'turtlesim/msg/Pose') as poses:
        first = poses.wait()
        assert first['x'] == pytest.approx(CENTRE, abs=1e-4)
        assert first['y'] == pytest.approx(CENTRE, abs=1e-4)
        assert first['theta'] == 0.0 and first['linear_velocity'] == 0.0
        start = time.monotonic()
        wait_for(lambda: len(poses.since(start)) >= 60, timeout=5)
        rate = len(poses.since(start)) / (time.monotonic() - start)
        assert 45 < rate < 75   # 62.5 Hz nominal


def test_drive_one_metre_per_second_for_two_seconds(fresh):
    """2 s of 1.0 m/s covers 2 m; the turtle then keeps the last command until 1 s of silence."""
    ros = fresh
    poses = Inbox(ros, '/turtle1/pose', 'turtlesim/msg/Pose')
    pub = roslibpy.Topic(ros, '/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
    try:
        poses.wait()
        pub.advertise()
        started = time.monotonic()
        last = stream(pub, twist(1.0), 2.0)
        at_last = poses.wait(after=last)
        moving = poses.wait(lambda m: m['linear_velocity'] > 0, after=started)
        assert moving['linear_velocity'] == pytest.approx(1.0)
        # 2 s (plus one message interval of rounding) after the first command
        assert at_last['x'] - CENTRE == pytest.approx(2.0, abs=0.15)
        stopped = poses.wait(lambda m: m['linear_velocity'] == 0.0, after=last, timeout=3)
        assert stopped['x'] - CENTRE == pytest.approx(2.95, abs=0.12)   # the real node: 2.93 m
        assert stopped['y'] == pytest.approx(CENTRE, abs=1e-4)
    finally:
        pub.unadvertise()
        poses.close()


def test_one_command_moves_for_one_second(fresh):
    ros = fresh
    assert spawn(ros, 'single', 1.0, 2.0) == 'single'
    pub = roslibpy.Topic(ros, '/single/cmd_vel', 'geometry_msgs/msg/Twist')
    with Inbox(ros, '/single/pose', 'turtlesim/msg/Pose') as poses:
        poses.wait()
        pub.publish(roslibpy.Message(twist(1.0, 0.5)))
        moving = poses.wait(lambda m: m['linear_velocity'] > 0)
        assert moving['angular_velocity'] == 0.5
        stopped = poses.wait(lambda m: m['linear_velocity'] == 0.0 and m['x'] > 1.0, timeout=3)
        travelled = 2 * math.asin(0.5 * 0.5 * 1.0) / 0.5 * 1.0   # chord of 1 s on a circle of radius 2
        assert math.hypot(stopped['x'] - 1.0, stopped['y'] - 2.0) == pytest.approx(travelled, abs=0.05)
        assert stopped['theta'] == pytest.approx(0.5, abs=0.02)
        time.sleep(0.3)
        assert poses.last['x'] == stopped['x']


def test_sideways_motion_only_when_holonomic(fresh):
    ros = fresh
    assert spawn(ros, 'crab', 3.0, 3.0) == 'crab'
    holonomic = roslibpy.Param(ros, '/turtlesim:holonomic')
    poses = Inbox(ros, '/crab/pose', 'turtlesim/msg/Pose')
    pub = roslibpy.Topic(ros, '/crab/cmd_vel', 'geometry_msgs/msg/Twist')
    sideways = {'linear': {'x': 0.0, 'y': 1.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}
    try:
        assert holonomic.get(timeout=5) is False
        pub.publish(roslibpy.Message(sideways))
        time.sleep(0.3)
        assert poses.last['y'] == pytest.approx(3.0, abs=1e-6) and poses.last['linear_velocity'] == 0.0
        holonomic.set(True, timeout=5)
        pub.publish(roslibpy.Message(sideways))
        moving = poses.wait(lambda m: m['y'] > 3.1)
        assert moving['x'] == pytest.approx(3.0, abs=1e-6) and moving['linear_velocity'] == 1.0
    finally:
        holonomic.set(False, timeout=5)
        poses.close()


def test_walls_clamp_the_pose_and_log_the_warning(fresh):
    ros = fresh
    with (Inbox(ros, '/rosout', 'rcl_interfaces/msg/Log') as log,
          Inbox(ros, '/turtle1/pose', 'turtlesim/msg/Pose') as poses):
        call(ros, '/turtle1/teleport_absolute', 'turtlesim/srv/TeleportAbsolute', {'x': 10.8, 'y': 3.0, 'theta': 0.0})
        poses.wait(lambda m: m['x'] == pytest.approx(10.8, abs=1e-3))
        pub = roslibpy.Topic(ros, '/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
        pub.publish(roslibpy.Message(twist(2.0)))
        clamped = poses.wait(lambda m: m['x'] >= SIZE - 1e-4)
        assert clamped['x'] == pytest.approx(SIZE, abs=1e-4) and clamped['y'] == pytest.approx(3.0, abs=1e-4)
        warning = log.wait(lambda m: m['msg'].startswith('Oh no! I hit the wall!'))
        assert warning['level'] == 30 and warning['name'] == 'turtlesim'
        assert 'Clamping from [x=' in warning['msg']
        time.sleep(0.1)
        assert poses.last['x'] == pytest.approx(SIZE, abs=1e-4)


def test_rotate_absolute_reaches_its_target_with_feedback(fresh):
    ros = fresh
    with Inbox(ros, '/turtle1/pose', 'turtlesim/msg/Pose') as poses:
        poses.wait()
        action = roslibpy.ActionClient(ros, '/turtle1/rotate_absolute', 'turtlesim/action/RotateAbsolute')
        results, feedback = [], []
        goal = action.send_goal(roslibpy.Goal({'theta': 1.2}), results.append, feedback.append, results.append)
        action.wait_goal(goal, timeout=5)
        assert results[0]['status'] == roslibpy.GoalStatus.SUCCEEDED
        assert results[0]['values']['delta'] == pytest.approx(-1.2, abs=0.02)
        remaining = [f['remaining'] for f in feedback]
        assert len(remaining) > 30 and remaining[0] == pytest.approx(1.2, abs=0.02)
        assert remaining == sorted(remaining, reverse=True) and remaining[-1] < 0.03
        settled = poses.wait(lambda m: m['angular_velocity'] == 0.0 and m['theta'] > 1.0)
        assert settled['theta'] == pytest.approx(1.2, abs=0.02)


def test_rotate_absolute_cancel_and_preemption(fresh):
    ros = fresh
    assert spawn(ros, 'spinner', 3.0, 3.0) == 'spinner'
    action = roslibpy.ActionClient(ros, '/spinner/rotate_absolute', 'turtlesim/action/RotateAbsolute')
    result = cancelled(action, {'theta': 3.0}, after_feedback=5, timeout=5)
    assert 0 < -result['values']['delta'] < 2.5

    first, second, fb = [], [], []
    g1 = action.send_goal(roslibpy.Goal({'theta': -2.0}), first.append, fb.append, first.append)
    wait_for(lambda: len(fb) >= 3)
    g2 = action.send_goal(roslibpy.Goal({'theta': 0.5}), second.append, lambda f: None, second.append)
    action.wait_goal(g1, timeout=5)
    assert first[0]['status'] == roslibpy.GoalStatus.ABORTED
    action.wait_goal(g2, timeout=8)
    assert second[0]['status'] == roslibpy.GoalStatus.SUCCEEDED

    # a velocity command aborts a running goal, as in the real node
    third = []
    g3 = action.send_goal(roslibpy.Goal({'theta': -2.5}), third.append, lambda f: None, third.append)
    time.sleep(0.2)
    roslibpy.Topic(ros, '/spinner/cmd_vel', 'geometry_msgs/msg/Twist').publish(roslibpy.Message(twist()))
    action.wait_goal(g3, timeout=5)
    assert third[0]['status'] == roslibpy.GoalStatus.ABORTED


def test_spawn_kill_and_teleport(fresh):
    ros = fresh
    assert spawn(ros, '', 1.0, 2.0, 0.5) == 'turtle2'
    assert spawn(ros, '', 2.0, 2.0) == 'turtle3'
    assert spawn(ros, 'turtle2', 2.0, 2.0) == ''            # the real node answers an empty name
    with pytest.raises(Exception):
        spawn(ros, 'not a name', 2.0, 2.0)
    wait_for(lambda: '/turtle2/pose' in ros.get_topics())
    assert ros.get_service_type('/turtle2/teleport_absolute') == 'turtlesim/srv/TeleportAbsolute'

    with Inbox(ros, '/turtle2/pose', 'turtlesim/msg/Pose') as poses:
        first = poses.wait()
        assert (first['x'], first['y'], first['theta']) == pytest.approx((1.0, 2.0, 0.5), abs=1e-5)
        call(ros, '/turtle2/teleport_absolute', 'turtlesim/srv/TeleportAbsolute', {'x': 4.0, 'y': 7.0, 'theta': 1.0})
        poses.wait(lambda m: m['x'] == pytest.approx(4.0, abs=1e-5) and m['y'] == pytest.approx(7.0, abs=1e-5))
        call(ros, '/turtle2/teleport_relative', 'turtlesim/srv/TeleportRelative',
             {'linear': 2.0, 'angular': math.pi / 2 - 1.0})
        moved = poses.wait(lambda m: m['y'] > 8.0)
        assert (moved['x'], moved['y'], moved['theta']) == pytest.approx((4.0, 9.0, math.pi / 2), abs=1e-4)

    call(ros, '/kill', 'turtlesim/srv/Kill', {'name': 'turtle2'})
    wait_for(lambda: '/turtle2/pose' not in ros.get_topics())
    assert '/turtle2/set_pen' not in ros.get_services()
    assert '/turtle3/set_pen' in ros.get_services()
    call(ros, '/kill', 'turtlesim/srv/Kill', {'name': 'turtle2'})   # logged, answered, as the real node


def test_set_pen_colour_sensor_and_clear(fresh):
    ros = fresh
    with (Inbox(ros, '/turtle1/color_sensor', 'turtlesim/msg/Color') as colours,
          Inbox(ros, '/world/markers', 'visualization_msgs/msg/MarkerArray') as markers):
        colours.wait(lambda m: m == UNPAINTED)     # nothing drawn until the turtle moves
        call(ros, '/turtle1/set_pen', 'turtlesim/srv/SetPen', {'r': 255, 'g': 0, 'b': 0, 'width': 9, 'off': 0})
        call(ros, '/turtle1/teleport_relative', 'turtlesim/srv/TeleportRelative', {'linear': 1.0, 'angular': 0.0})
        colours.wait(lambda m: m == {'r': 255, 'g': 0, 'b': 0})
        red = markers.wait(lambda m: any(_red_pen(x) for x in m['markers']))
        line = next(x for x in red['markers'] if _red_pen(x))
        assert line['type'] == 5 and line['scale']['x'] == pytest.approx(9 / 45)
        ends = [(p['x'], p['y']) for p in line['points']]
        assert ends[0] == pytest.approx((CENTRE, CENTRE), abs=1e-4)
        assert ends[-1] == pytest.approx((CENTRE + 1.0, CENTRE), abs=1e-4)

        call(ros, '/turtle1/set_pen', 'turtlesim/srv/SetPen', {'r': 0, 'g': 255, 'b': 0, 'width': 3, 'off': 1})
        call(ros, '/turtle1/teleport_absolute', 'turtlesim/srv/TeleportAbsolute', {'x': 2.0, 'y': 9.0, 'theta': 0.0})
        colours.wait(lambda m: m == UNPAINTED)      # no trail with the pen off

        t = time.monotonic()
        call(ros, '/clear', 'std_srvs/srv/Empty')
        cleared = markers.wait(lambda m: any(x['ns'] == 'pen' and x['action'] == 3 for x in m['markers']), after=t)
        assert cleared
        call(ros, '/turtle1/teleport_absolute', 'turtlesim/srv/TeleportAbsolute',
             {'x': CENTRE + 0.5, 'y': CENTRE, 'theta': 0.0})
        colours.wait(lambda m: m == UNPAINTED, after=time.monotonic())   # the red trail is gone


def _red_pen(m: dict) -> bool:
    return m['ns'] == 'pen' and m['action'] == 0 and m['color']['r'] == 1.0 and m['color']['g'] == 0.0


def test_background_parameters_through_rosapi(fresh):
    ros = fresh
    r = roslibpy.Param(ros, '/turtlesim:background_r')
    try:
        assert r.get(timeout=5) == 69
        assert roslibpy.Param(ros, '/turtlesim:background_b').get(timeout=5) == 255
        markers = Inbox(ros, '/world/markers', 'visualization_msgs/msg/MarkerArray')
        r.set(150, timeout=5)
        assert r.get(timeout=5) == 150
        bounds = markers.wait(lambda m: any(x['ns'] == 'bounds' and x['color']['r'] == pytest.approx(150 / 255)
                                            for x in m['markers']))
        assert bounds
        markers.close()
        result = rosapi(ros, 'set_param', 'SetParam', name='/turtlesim:background_r', value='300')
        assert result['successful'] is False and '255' in result['reason']
        assert r.get(timeout=5) == 150
    finally:
        r.set(69, timeout=5)


def test_world_markers_snapshot_and_updates(fresh):
    ros = fresh
    call(ros, '/turtle1/teleport_absolute', 'turtlesim/srv/TeleportAbsolute', {'x': 3.0, 'y': 4.0, 'theta': 0.3})
    assert spawn(ros, 'viewed', 8.0, 8.0) == 'viewed'
    with Inbox(ros, '/world/markers', 'visualization_msgs/msg/MarkerArray') as markers:
        view = {}

        def apply():
            for msg in markers.messages:
                for m in msg['markers']:
                    if m['action'] == 3:
                        for key in [k for k in view if k[0] == m['ns'] or not m['ns']]:
                            del view[key]
                    elif m['action'] == 2:
                        view.pop((m['ns'], m['id']), None)
                    else:
                        view[(m['ns'], m['id'])] = m
            return view

        def turtles():
            return {m['text']: m for (ns, _), m in apply().items() if ns == 'robots'}

        wait_for(lambda: {'turtle1', 'viewed'} <= set(turtles()))
        bounds = [m for (ns, _), m in view.items() if ns == 'bounds']
        assert len(bounds) == 1 and bounds[0]['header']['frame_id'] == 'world'
        assert bounds[0]['scale']['x'] == pytest.approx(SIZE, abs=1e-4)
        arrow = turtles()['turtle1']
        assert arrow['type'] == 0
        assert (arrow['pose']['position']['x'], arrow['pose']['position']['y']) == pytest.approx((3.0, 4.0), abs=1e-4)
        assert 2 * math.atan2(arrow['pose']['orientation']['z'], arrow['pose']['orientation']['w']) == \
            pytest.approx(0.3, abs=1e-4)
        # the teleport's trail is in the snapshot too
        assert any(ns == 'pen' for ns, _ in view)
        call(ros, '/kill', 'turtlesim/srv/Kill', {'name': 'viewed'})
        wait_for(lambda: 'viewed' not in turtles())


def test_reset_restores_the_start(fresh):
    ros = fresh
    assert spawn(ros, '', 1.0, 1.0) == 'turtle2'
    call(ros, '/turtle1/teleport_absolute', 'turtlesim/srv/TeleportAbsolute', {'x': 1.0, 'y': 1.0, 'theta': 2.0})
    call(ros, '/reset', 'std_srvs/srv/Empty')
    wait_for(lambda: '/turtle2/pose' not in ros.get_topics())
    with Inbox(ros, '/turtle1/pose', 'turtlesim/msg/Pose') as poses:
        pose = poses.wait()
        assert (pose['x'], pose['y'], pose['theta']) == pytest.approx((CENTRE, CENTRE, 0.0), abs=1e-4)
    assert spawn(ros, '', 1.0, 1.0) == 'turtle2'   # the counter starts over


def test_a_viewer_joining_late_gets_the_whole_world(fresh, turtle_gw):
    """Two viewers share the gateway's subscription; the second still gets bounds, trails, turtles."""
    ros = fresh
    with Inbox(ros, '/world/markers', 'visualization_msgs/msg/MarkerArray') as first:
        first.wait(lambda m: any(x['ns'] == 'bounds' for x in m['markers']))
        call(ros, '/turtle1/teleport_relative', 'turtlesim/srv/TeleportRelative', {'linear': 1.0, 'angular': 0.0})
        first.wait(lambda m: any(x['ns'] == 'pen' and x['action'] == 0 for x in m['markers']))
        time.sleep(0.3)  # let a few robot-only updates pass, so the snapshot is not the newest message
        with client(turtle_gw) as late_ros:
            late = Inbox(late_ros, '/world/markers', 'visualization_msgs/msg/MarkerArray')
            snapshot = late.wait()
            kinds = {x['ns'] for x in snapshot['markers']}
            assert {'bounds', 'pen', 'robots'} <= kinds


def test_non_finite_and_huge_commands_leave_turtlesim_working(fresh):
    """NaN or 1e308 from one client must not break the turtle (or its timer) for everyone."""
    ros = fresh
    poses = Inbox(ros, '/turtle1/pose', 'turtlesim/msg/Pose')
    pub = roslibpy.Topic(ros, '/turtle1/cmd_vel', 'geometry_msgs/msg/Twist')
    try:
        with pytest.raises(Exception, match='finite'):
            call(ros, '/turtle1/teleport_absolute', 'turtlesim/srv/TeleportAbsolute',
                 {'x': float('nan'), 'y': 1.0, 'theta': 0.0})
        with pytest.raises(Exception, match='finite'):
            call(ros, '/turtle1/teleport_relative', 'turtlesim/srv/TeleportRelative',
                 {'linear': float('inf'), 'angular': 0.0})
        t = time.monotonic()
        pub.publish(roslibpy.Message(twist(x=1e308, z=-1e308)))
        moved = poses.wait(lambda m: m['linear_velocity'] > 0, after=t)
        assert all(math.isfinite(moved[k]) for k in ('x', 'y', 'theta'))
        assert 0 <= moved['x'] <= SIZE and 0 <= moved['y'] <= SIZE
        pub.publish(roslibpy.Message(twist()))
        poses.wait(lambda m: m['linear_velocity'] == 0, after=time.monotonic())
        call(ros, '/turtle1/teleport_absolute', 'turtlesim/srv/TeleportAbsolute', {'x': 3.0, 'y': 4.0, 'theta': 0.5})
        t = time.monotonic()
        back = poses.wait(lambda m: m['linear_velocity'] == 0 and abs(m['x'] - 3.0) < 1e-3, after=t, timeout=10)
        assert back['y'] == pytest.approx(4.0, abs=1e-3) and back['theta'] == pytest.approx(0.5, abs=1e-3)
    finally:
        pub.unadvertise()
        poses.close()
