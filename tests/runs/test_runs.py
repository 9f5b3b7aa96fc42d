"""Robot-side runs (/api/runs): real processes running the generated-Python runtime against a
live gateway, followed over rosbridge with roslibpy."""

from __future__ import annotations

import json
import queue
import threading
import time
import uuid

import pytest
import roslibpy

from tests.support.auth import TOKENS, tokens_toml
from tests.support.http import api
from tests.support.ros import client as connect
from tests.support.runs import alive, ended, program, state_of
from tests.support.wait import wait_for

TWIST = 'geometry_msgs/msg/Twist'
GO = 'rt.wait_for_message("/run_test/go", "std_msgs/msg/String")'


@pytest.fixture(scope='module')
def runs_gw(start_gateway, tmp_path_factory):
    runs_dir = tmp_path_factory.mktemp('runs')
    gw = start_gateway('--robot', 'turtlesim', '--allow-runs', '--runs-dir', str(runs_dir),
                       env={'ROSGATE_TEST_SECRET': 'do-not-leak'})
    gw.runs_dir = runs_dir
    return gw


@pytest.fixture
def client(runs_gw):
    with connect(runs_gw) as ros:
        yield ros


def follow(ros, topic: str, type: str = 'std_msgs/msg/String') -> queue.Queue:
    """Messages of a topic as they arrive, in order, with their arrival time."""
    q: queue.Queue = queue.Queue()
    roslibpy.Topic(ros, topic, type).subscribe(lambda m: q.put((time.monotonic(), m)))
    return q


def go(ros) -> None:
    roslibpy.Topic(ros, '/run_test/go', 'std_msgs/msg/String').publish(roslibpy.Message({'data': 'go'}))


def start(gw, source: str, ns: str, **kw) -> str:
    status, body = api(gw, 'POST', '/api/runs', {'source': source, 'name': kw.pop('name', 'test'), 'ns': ns, **kw})
    assert status == 201, body
    return body['id']


def wait_for_subscriber(ros, topic: str) -> None:
    """The run is listening once the go topic has a subscriber (its process connected)."""
    def has():
        out = {}
        done = threading.Event()
        roslibpy.Service(ros, '/rosapi/subscribers', 'rosapi/Subscribers').call(
            roslibpy.ServiceRequest({'topic': topic}), lambda r: (out.update(r), done.set()), lambda e: done.set())
        done.wait(5)
        return out.get('subscribers')
    wait_for(has, 60, 0.1)


def test_run_moves_the_turtle_and_streams_output_in_order(runs_gw, client):
    pose = follow(client, '/turtle1/pose', 'turtlesim/msg/Pose')
    x0 = pose.get(timeout=10)[1]['x']
    run_id = start(runs_gw, program(f'''
{GO}
for i in range(20):
    rt.log("line %d" % i)
rt.drive("/turtle1/cmd_vel", "{TWIST}", {{"linear": {{"x": 2.0}}}}, 1.0)
rt.log("done")
'''), '')
    output = follow(client, f'/rosgate/runs/{run_id}/output')
    states = follow(client, f'/rosgate/runs/{run_id}/state')
    wait_for_subscriber(client, '/run_test/go')
    go(client)
    body = ended(runs_gw, run_id)
    assert body['state'] == 'finished' and body['exit_code'] == 0, body
    lines = []
    wait_for(lambda: lines.extend(m['data'] for _, m in iter_queue(output)) or 'done' in lines, 10)
    assert lines[:21] == [f'line {i}' for i in range(20)] + ['done']
    assert body['output'].startswith(''.join(f'line {i}\n' for i in range(20)) + 'done\n')
    seen = [json.loads(m['data'])['state'] for _, m in iter_queue(states)]
    assert seen[-1] == 'finished' and 'running' in seen
    latest = None
    while not pose.empty():
        latest = pose.get()[1]
    assert latest['x'] > x0 + 1.0, (x0, latest)


def iter_queue(q: queue.Queue):
    while True:
        try:
            yield q.get_nowait()
        except queue.Empty:
            return


def test_delete_stops_it_and_the_zero_twist_arrives_within_200_ms(runs_gw, client):
    run_id = start(runs_gw, program(f'''
rt.log("driving")
while True:
    rt.publish("/turtle1/cmd_vel", "{TWIST}", {{"angular": {{"z": 1.0}}}})
    rt.sleep(0.05)
'''), '')
    cmd = follow(client, '/turtle1/cmd_vel', TWIST)
    moving = lambda m: m['angular']['z'] != 0 or m['linear']['x'] != 0   # noqa: E731
    wait_for(lambda: any(moving(m) for _, m in iter_queue(cmd)), 30)
    sent = time.monotonic()
    status, body = api(runs_gw, 'DELETE', f'/api/runs/{run_id}')
    assert status in (200, 202), body
    while True:
        at, m = cmd.get(timeout=5)
        if at >= sent and not moving(m):
            break
    latency = at - sent
    print(f'zero Twist {latency * 1000:.1f} ms after DELETE was sent')
    assert latency < 0.2
    final = ended(runs_gw, run_id)
    assert final['state'] == 'stopped'
    assert not any(moving(m) for t, m in iter_queue(cmd) if t > at), 'the run moved the robot after its stop'


def test_timeout_ends_the_run_timed_out(runs_gw):
    run_id = start(runs_gw, program('rt.log("waiting")\nrt.sleep(120)'), '', timeout=1)
    body = ended(runs_gw, run_id)
    assert body['state'] == 'timed_out', body
    assert 'timeout' in body['reason']


def test_memory_limit_fails_the_run_with_the_reason(runs_gw):
    run_id = start(runs_gw, program('rt.log("allocating")\nhog = bytearray(3 * 2**30)\nrt.log("got it")'), '')
    body = ended(runs_gw, run_id)
    assert body['state'] == 'failed', body
    assert 'memory limit' in body['reason'], body
    assert 'got it' not in body['output']


def test_second_run_in_a_namespace_is_refused_naming_the_first(runs_gw):
    first = start(runs_gw, program('rt.sleep(60)'), '', name='first one')
    status, body = api(runs_gw, 'POST', '/api/runs', {'source': program('rt.sleep(1)'), 'ns': '/'})
    assert status == 409, body
    assert first in body['error'] and 'first one' in body['error']
    api(runs_gw, 'DELETE', f'/api/runs/{first}')
    assert ended(runs_gw, first)['state'] == 'stopped'


def sleeper(marker: str) -> str:
    """Program lines starting a child process that sleeps with ``marker`` in its command line."""
    return f'child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(300)", "{marker}"])'


def test_the_process_its_environment_directory_and_group(runs_gw):
    marker = f'rosgate-test-{uuid.uuid4().hex}'
    run_id = start(runs_gw, program(f'''
import subprocess
{sleeper(marker)}
rt.log("cwd %s" % os.getcwd())
rt.log("env %s" % " ".join(sorted(os.environ)))
signal.signal(signal.SIGINT, signal.SIG_IGN)
while True:
    signal.pause()
'''), '')
    body = wait_for(lambda: (lambda b: b if 'env ' in b['output'] else None)(state_of(runs_gw, run_id)), 30)
    lines = dict(line.split(' ', 1) for line in body['output'].splitlines() if ' ' in line)
    assert lines['cwd'] == '/home/run'   # in the sandbox; the program is kept in the run's directory
    assert (runs_gw.runs_dir / run_id / 'program.py').is_file()
    assert 'ROSGATE_TEST_SECRET' not in lines['env'] and 'do-not-leak' not in body['output']
    assert set(lines['env'].split()) <= {'PATH', 'HOME', 'LANG', 'LC_CTYPE', 'PWD', 'PYTHONUNBUFFERED',
                                         'PYTHONDONTWRITEBYTECODE', 'ROSBRIDGE_URL', 'ROSGATE_NS', 'ROSGATE_RUN'}
    wait_for(lambda: alive(marker), 10)
    api(runs_gw, 'DELETE', f'/api/runs/{run_id}')      # it ignores SIGINT: SIGKILL after 2 s
    final = ended(runs_gw, run_id)
    assert final['state'] == 'stopped' and final['exit_code'] == -9, final
    wait_for(lambda: not alive(marker), 10)   # the whole process group went


def test_a_library_program_runs_by_name(runs_gw):
    source = program('rt.log("from the library")')
    assert api(runs_gw, 'PUT', '/api/programs/lib%20run', {'format': 'rosgate-program', 'python': source})[0] == 200
    status, body = api(runs_gw, 'POST', '/api/runs', {'program': 'lib run'})
    assert status == 201, body
    final = ended(runs_gw, body['id'])
    assert final['state'] == 'finished' and 'from the library' in final['output'] and final['name'] == 'lib run'
    status, body = api(runs_gw, 'POST', '/api/runs', {'program': 'not there'})
    assert status == 404, body


def test_bad_requests_are_refused_clearly(runs_gw):
    for body, word in (({}, 'source'), ({'source': 'x', 'timeout': -1}, 'timeout'),
                       ({'source': 'x', 'ns': '../etc'}, 'ns')):
        status, reply = api(runs_gw, 'POST', '/api/runs', body)
        assert status == 400 and word in reply['error'], reply
    status, reply = api(runs_gw, 'POST', '/api/runs', {'source': 'x'}, headers={'Origin': 'http://evil.example'})
    assert status == 403, reply
    assert api(runs_gw, 'GET', '/api/runs/rnothere')[0] == 404


def test_without_allow_runs_the_api_answers_403(gateway):
    status, body = api(gateway, 'GET', '/api/runs')
    assert status == 200 and body['allowed'] is False
    status, body = api(gateway, 'POST', '/api/runs', {'source': program('rt.log(1)')})
    assert status == 403 and '--allow-runs' in body['error']


@pytest.fixture(scope='module')
def auth_gw(start_gateway, tmp_path_factory):
    folder = tmp_path_factory.mktemp('auth-runs')
    (folder / 'tokens.toml').write_text(tokens_toml())
    return start_gateway('--robot', 'turtlesim', '--allow-runs', '--runs-dir', str(folder / 'runs'),
                         '--auth', str(folder / 'tokens.toml'), '--exclusive-control')


def signed_in(gw, who: str):
    ros = roslibpy.Ros(gw.host, gw.port)
    ros.run(timeout=10)
    ros.send_on_ready(roslibpy.Message({'op': 'auth', 'token': TOKENS[who]}))
    return ros


def drivers_seen(q: queue.Queue, seen: list) -> list:
    seen.extend(json.loads(m['data'])['driver'] for _, m in iter_queue(q))
    return seen


def test_viewer_refused_operator_runs_with_its_role(auth_gw):
    gw = auth_gw
    source = program('rt.log("x=%.1f" % rt.latest("/turtle1/pose", "turtlesim/msg/Pose", "x"))\n'
                     f'rt.drive("/turtle1/cmd_vel", "{TWIST}", {{"linear": {{"x": 0.5}}}}, 0.3)')
    assert api(gw, 'POST', '/api/runs', {'source': source})[0] == 401
    status, body = api(gw, 'POST', '/api/runs', {'source': source}, token=TOKENS['viewer'])
    assert status == 403 and 'operator' in body['error']
    assert api(gw, 'GET', '/api/runs', token=TOKENS['viewer'])[0] == 200

    ros = signed_in(gw, 'viewer')
    try:
        drivers = follow(ros, '/rosgate/driver')
        status, body = api(gw, 'POST', '/api/runs', {'source': source}, token=TOKENS['operator'])
        assert status == 201, body
        run_id = body['id']
        final = ended(gw, run_id, token=TOKENS['operator'])
        assert final['state'] == 'finished', final
        assert 'x=' in final['output']   # its connection has the operator's role: it may subscribe
        seen: list = []
        wait_for(lambda: (lambda d: any(x and x['name'] == f'run {run_id}' for x in d) and d[-1] is None)(
            drivers_seen(drivers, seen)), 10)   # the run drove, then gave the lease back
    finally:
        ros.close()


def test_a_library_program_runs_by_name_from_the_callers_own_space(auth_gw):
    gw = auth_gw
    source = program('rt.log("from my space")')
    status, body = api(gw, 'PUT', '/api/programs/mine', {'format': 'rosgate-program', 'python': source},
                       token=TOKENS['operator'])
    assert status == 200, body   # with --auth it lands in the operator's own space, as the IDE's save does
    status, body = api(gw, 'POST', '/api/runs', {'program': 'mine'}, token=TOKENS['operator'])
    assert status == 201, body
    final = ended(gw, body['id'], token=TOKENS['admin'])
    assert final['state'] == 'finished' and 'from my space' in final['output'], final
    # another operator's library has no such program, and may not reach into the first one's
    assert api(gw, 'POST', '/api/runs', {'program': 'mine'}, token=TOKENS['operator2'])[0] == 404
    owner = api(gw, 'GET', '/api/programs', token=TOKENS['operator'])[1]['programs'][0]['owner']
    status, body = api(gw, 'POST', '/api/runs', {'program': 'mine', 'owner': owner}, token=TOKENS['operator2'])
    assert status == 403, body


def alice_drives(gw):
    """alice signed in and holding the driver lease: (her client, the /rosgate/driver messages,
    the drivers seen so far)."""
    alice = signed_in(gw, 'operator')
    drivers = follow(alice, '/rosgate/driver')
    roslibpy.Topic(alice, '/rosgate/control', 'std_msgs/msg/String').publish(roslibpy.Message({'data': 'take'}))
    seen: list = []
    wait_for(lambda: (lambda d: d and d[-1] and d[-1]['name'] == 'alice')(drivers_seen(drivers, seen)), 10)
    return alice, drivers, seen


def holding(topic: str) -> str:
    """A run that holds until a message on ``topic``."""
    return program(f'rt.log("holding")\nrt.wait_for_message("{topic}", "std_msgs/msg/String")')


def lease_goes_to_the_run(drivers: queue.Queue, seen: list, run_id: str) -> None:
    wait_for(lambda: (lambda d: d[-1] and d[-1]['name'] == f'run {run_id}')(drivers_seen(drivers, seen)), 30)


def let_go(ros, topic: str) -> None:
    """The message a holding run waits for, once it listens."""
    wait_for_subscriber(ros, topic)
    roslibpy.Topic(ros, topic, 'std_msgs/msg/String').publish(roslibpy.Message({'data': 'done'}))


def test_run_takes_the_lease_when_it_starts(auth_gw):
    gw = auth_gw
    alice, drivers, seen = alice_drives(gw)
    try:
        quiet = holding('/run_test/done')
        status, body = api(gw, 'POST', '/api/runs', {'source': quiet}, token=TOKENS['operator2'])
        assert status == 409 and 'alice' in body['error'], body        # bob may not take it from alice
        status, body = api(gw, 'POST', '/api/runs', {'source': quiet}, token=TOKENS['admin'])
        assert status == 201, body                                     # the teacher's run takes over
        run_id = body['id']
        lease_goes_to_the_run(drivers, seen, run_id)
        assert state_of(gw, run_id, TOKENS['admin'])['state'] == 'running'   # it has not commanded anything
        let_go(alice, '/run_test/done')
        assert ended(gw, run_id, token=TOKENS['admin'])['state'] == 'finished'
        wait_for(lambda: drivers_seen(drivers, seen)[-1] is None, 10)   # and it gave the lease back
    finally:
        alice.close()


def test_her_own_run_takes_her_lease_and_gives_it_back(auth_gw):
    """Run on robot while she drives: no Release first; when the run ends she drives again."""
    gw = auth_gw
    alice, drivers, seen = alice_drives(gw)
    try:
        status, body = api(gw, 'POST', '/api/runs', {'source': holding('/run_test/done2')}, token=TOKENS['operator'])
        assert status == 201, body
        run_id = body['id']
        lease_goes_to_the_run(drivers, seen, run_id)
        let_go(alice, '/run_test/done2')
        final = ended(gw, run_id, token=TOKENS['admin'])
        assert final['state'] == 'finished' and 'driver lease' not in final['output'], final
        wait_for(lambda: (lambda d: d and d[-1] and d[-1]['name'] == 'alice')(drivers_seen(drivers, seen)), 10)
    finally:
        roslibpy.Topic(alice, '/rosgate/control', 'std_msgs/msg/String').publish(roslibpy.Message({'data': 'release'}))
        alice.close()


def test_a_child_left_behind_does_not_keep_the_run_going(runs_gw):
    marker = f'rosgate-test-{uuid.uuid4().hex}'
    run_id = start(runs_gw, program(f'''
import subprocess
{sleeper(marker)}
rt.log("child started")
'''), '')
    final = ended(runs_gw, run_id)
    assert final['state'] == 'finished', final
    wait_for(lambda: not alive(marker), 10)


def test_output_is_capped(runs_gw):
    run_id = start(runs_gw, program('''
line = "y" * 1000
for i in range(6000):
    print(line)
print("z" * 10000)
rt.log("end")
'''), '')
    final = ended(runs_gw, run_id)
    assert final['state'] == 'finished', final['reason']
    assert 'output limit of 4194304 bytes reached' in final['output']
    assert len(final['output']) <= 64 * 1024 + 4096
    assert 'end' not in final['output'].splitlines()
    assert final['output'].endswith('[run finished]\n')


def test_trusted_runs_need_allow_runs(start_gateway):
    with pytest.raises(RuntimeError) as refused:
        start_gateway('--trusted-runs')
    assert 'rosgate: --trusted-runs: it is a kind of run: give --allow-runs too' in str(refused.value)


def test_a_ros2_node_run_is_an_rclpy_program_on_a_trusted_gateway_only(runs_gw):
    """Runs here are not nodes of the graph: the listing says so, and a node run is refused saying
    why; what a node run takes is an rclpy program as it is (gateway/runs/node.py)."""
    from gateway.runs.node import node_arguments, node_program
    status, body = api(runs_gw, 'GET', '/api/runs')
    assert status == 200 and body['allowed'] is True and body['nodes'] is False
    status, body = api(runs_gw, 'POST', '/api/runs', {'source': 'import rclpy\n', 'kind': 'ros2_node'})
    assert status == 400 and '--trusted-runs' in body['error'], body
    node = 'import rclpy\nfrom rclpy.node import Node\n\nrclpy.init()\nNode("n")\n'
    assert node_program(node) == node
    assert node_program('from rclpy.node import Node\n') == 'from rclpy.node import Node\n'
    for source in ('print(1)\n', '# import rclpy\n', 'import rclpyx\n'):
        try:
            node_program(source)
        except ValueError as e:
            assert 'rclpy' in str(e)
        else:
            raise AssertionError(f'{source!r} taken as a node')
    assert node_arguments('/s07') == ['--ros-args', '-r', '__ns:=/s07'] and node_arguments('') == []


def test_a_run_whose_recording_is_refused_stops_at_once_saying_why(runs_gw):
    """A run asked to be recorded is not run unrecorded: with every recording slot taken it is
    stopped as it starts, and the answer (409) says the recording was refused and why."""
    taken = []
    try:
        for _ in range(8):   # the recordings' concurrent cap (4 by default), whatever is left running
            status, body = api(runs_gw, 'POST', '/api/recordings', {'topics': ['/turtle1/pose'], 'max_seconds': 120})
            if status != 201:
                break
            taken.append(body['id'])
        assert status == 409 and 'recordings are already running' in body['error'], body
        status, body = api(runs_gw, 'POST', '/api/runs', {'source': program('rt.sleep(60)'), 'record': True})
        assert status == 409, body
        words = body['error']
        assert 'stopped: its recording was refused' in words and 'recordings are already running' in words, body
        run_id = words.split()[1]
        assert ended(runs_gw, run_id)['state'] == 'stopped'
    finally:
        for rec_id in taken:
            api(runs_gw, 'DELETE', f'/api/recordings/{rec_id}')
