"""rclpy in the IDE page (ide/runtime/browser/rclpy, Pyodide in a worker), in Chromium, on
`--robot turtlesim`: the ROS 2 Jazzy tutorials' Python nodes (tests/ide/ros2_tutorials/, their exact
text) run unchanged with the page's Run and talk to roslibpy clients through the gateway; the
publisher and the service are typed into the editor key by key. The node the IDE generates from
each example runs there too and does what its blocks do (the rover's: tests/ide/test_rclpy_rover.py).
Mistakes read as on a ROS 2 machine: rclpy's own field checks, an unknown type's ImportError."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from tests.support.ide import IdePage, error_line
from tests.support.ros import Inbox, client
from tests.support.servers import check_served, program as served_program
from tests.support.wait import wait_for

from .test_text_python import type_python

TUTORIALS = Path(__file__).parent / 'ros2_tutorials'
PYODIDE_START = 120   # s: Pyodide's cold start on a busy 2-core machine
TWIST = 'geometry_msgs/msg/Twist'


@pytest.fixture(scope='module')
def gw(turtle_gateway):
    return turtle_gateway


@pytest.fixture(scope='module')
def browser_ctx(chromium):
    ctx = chromium.new_context(viewport={'width': 1400, 'height': 860})
    yield ctx
    ctx.close()


def page(ctx, gw, ns: str = '') -> IdePage:
    """A page on a new Python text program (Pyodide starting as it opens), in robot namespace ns."""
    ide = IdePage(ctx.new_page(), gw)
    ide.open(gw.http_url + '?mode=text&lang=python' + (f'&ns={ns}' if ns else ''))
    ide.page.wait_for_selector('.cm-content')
    ide.page.wait_for_function('rosgateIde.graph.loaded')
    return ide


@pytest.fixture(scope='module')
def ide(browser_ctx, gw):
    return page(browser_ctx, gw)


def load(ide: IdePage, text: str, name: str = 'tutorial'):
    ide.js('(p) => rosgateIde.loadProgram(p)',
           {'format': 'rosgate-program', 'version': 1, 'kind': 'text', 'lang': 'python', 'name': name, 'text': text})


def run(ide: IdePage, args: str = ''):
    # a loaded machine may have made the page's link again just now: Run needs it
    ide.page.wait_for_function("document.body.dataset.connection === 'connected'", timeout=60000)
    runs = ide.js('rosgateIde.textRunner.runs')
    ide.page.fill('.text-args', args)
    ide.page.click('#run')
    ide.page.wait_for_function(f'rosgateIde.textRunner.runs > {runs}')


def stop(ide: IdePage):
    ide.page.click('#stop')
    ide.page.wait_for_function("document.body.dataset.run === 'idle'")


def console(ide: IdePage) -> str:
    return ide.console_lines()


def logged(ide: IdePage, text: str, timeout: float = PYODIDE_START) -> str:
    return ide.logged(text, timeout)


def test_the_publisher_tutorial_typed_in_talks_to_roslibpy(ide, turtle):
    heard = turtle.watch('/topic', 'std_msgs/msg/String')
    type_python(ide, (TUTORIALS / 'publisher_member_function.py').read_text().rstrip('\n').split('\n'))
    run(ide)
    wait_for(lambda: len(heard.messages) >= 3, PYODIDE_START, what='three messages on /topic')
    numbers = [int(m['data'].split(': ')[1]) for _, m in heard.messages]
    assert numbers == list(range(numbers[0], numbers[0] + len(numbers)))
    assert all(m['data'].startswith('Hello World: ') for _, m in heard.messages)
    text = logged(ide, 'Publishing: "Hello World: 2"')
    assert '[INFO] [' in text and '] [minimal_publisher]: Publishing: "Hello World: 0"' in text
    stop(ide)
    assert 'stopped: Stop was pressed' in console(ide)
    # the gateway no longer counts the page as a publisher of /topic; from then on nothing comes
    wait_for(lambda: not turtle.call('/rosapi/publishers', 'rosapi/srv/Publishers', {'topic': '/topic'})['publishers'],
             what='the page no longer publishing /topic')
    t0 = time.monotonic()
    turtle.call('/rosapi/get_time', 'rosapi/srv/GetTime')   # a round trip after it
    assert not heard.since(t0), 'the node went on after Stop'


def test_the_subscriber_tutorial_hears_roslibpy(ide, turtle):
    load(ide, (TUTORIALS / 'subscriber_member_function.py').read_text())
    run(ide)
    # it subscribes once it runs: roslibpy publishes until the page hears
    topic = turtle.roslibpy.Topic(turtle.ros, '/topic', 'std_msgs/msg/String')
    end = time.monotonic() + PYODIDE_START
    while 'I heard: "from roslibpy"' not in console(ide) and time.monotonic() < end:
        topic.publish(turtle.roslibpy.Message({'data': 'from roslibpy'}))
        time.sleep(0.2)
    assert '[minimal_subscriber]: I heard: "from roslibpy"' in console(ide), console(ide)[-2000:]
    stop(ide)


def test_the_service_tutorial_typed_in_answers_roslibpy(ide, turtle):
    """The tutorial's server takes /add_two_ints (the sim's demo server steps aside meanwhile)."""
    type_python(ide, (TUTORIALS / 'service_member_function.py').read_text().rstrip('\n').split('\n'))
    run(ide)

    def asked():
        try:
            turtle.call('/add_two_ints', 'example_interfaces/srv/AddTwoInts', {'a': 2, 'b': 40}, timeout=5)
        except Exception:   # noqa: BLE001: not served yet
            return False
        return 'Incoming request' in console(ide)
    wait_for(asked, PYODIDE_START, 0.5, 'the page serving /add_two_ints')
    assert turtle.call('/add_two_ints', 'example_interfaces/srv/AddTwoInts', {'a': 5, 'b': 37})['sum'] == 42
    assert 'Incoming request\na: 5 b: 37' in console(ide)
    stop(ide)
    # the demo server is back once the page's has gone
    wait_for(lambda: turtle.call('/add_two_ints', 'example_interfaces/srv/AddTwoInts', {'a': 1, 'b': 1})['sum'] == 2,
             what='the demo /add_two_ints back')


def test_the_client_tutorial_takes_its_numbers_as_arguments(ide):
    load(ide, (TUTORIALS / 'client_member_function.py').read_text())
    run(ide, '2 3')
    text = logged(ide, 'Result of add_two_ints: for 2 + 3 = 5')
    assert '[minimal_client_async]' in text
    wait_for(lambda: ide.js("document.body.dataset.run") == 'idle', PYODIDE_START, what='the end of the run')
    assert 'finished' in console(ide).split('Result of add_two_ints')[1]


def test_the_action_tutorial_server_and_client(browser_ctx, gw, turtle):
    """Its server in one page and its client in another, both in robot namespace /s01 (the sim's demo
    /fibonacci is another type); roslibpy's goal to the server gets the same answers."""
    server = page(browser_ctx, gw, '/s01')
    load(server, (TUTORIALS / 'fibonacci_action_server.py').read_text(), 'server')
    run(server)
    result, feedback = {}, []
    client = turtle.roslibpy.ActionClient(turtle.ros, '/s01/fibonacci', 'custom_action_interfaces/action/Fibonacci')

    def served():
        return '/s01/fibonacci' in turtle.call('/rosapi/action_servers', 'rosapi/srv/GetActionServers')['action_servers']
    wait_for(served, PYODIDE_START, 0.5, 'the page serving /s01/fibonacci')
    goal = client.send_goal(turtle.roslibpy.Goal({'order': 3}), result.update, lambda f: feedback.append(list(f['partial_sequence'])),
                            lambda e: result.update(error=e))
    client.wait_goal(goal, timeout=30)
    assert list(result['values']['sequence']) == [0, 1, 1, 2], result
    assert feedback == [[0, 1, 1], [0, 1, 1, 2]], feedback
    assert 'Executing goal...' in console(server)

    user = page(browser_ctx, gw, '/s01')
    source = (TUTORIALS / 'fibonacci_action_client.py').read_text()
    load(user, source.replace('send_goal(10)', 'send_goal(4)'), 'client')   # 4 steps of the server's 1 s, not 9
    run(user)
    text = logged(user, "Result: array('i', [0, 1, 1, 2, 3])", PYODIDE_START)
    assert 'Goal accepted :)' in text and "Received feedback: array('i', [0, 1, 1])" in text
    wait_for(lambda: user.js("document.body.dataset.run") == 'idle', what='the client ends (rclpy.shutdown())')
    stop(server)
    assert not server.errors and not user.errors, (server.errors, user.errors)


def node_of(ide: IdePage, example: str) -> str:
    ide.load_example(example)
    return ide.js('async () => rosgateIde.rosNode()')


@pytest.mark.parametrize('example, said', [
    ('drive_square.json', 'square done'),
    ('spiral.json', 'spiral done at x = '),
    ('three_turtles.json', '[spawn_three_turtles_and_move_each]: turtle4'),
    ('fibonacci.json', "array('i', [0, 1, 1, 2, 3, 5, 8, 13, 21])"),
])
def test_the_node_of_each_turtlesim_example_runs_in_the_page(ide, turtle, example, said):
    """The generated node, loaded as a text program of the page and run: it does what the blocks do,
    and ends by itself."""
    pose = turtle.watch('/turtle1/pose', 'turtlesim/msg/Pose')
    wait_for(pose.latest, what='a pose')
    before = pose.latest()
    code = node_of(ide, example)
    load(ide, code, example)
    run(ide)
    logged(ide, said, PYODIDE_START)
    wait_for(lambda: ide.js("document.body.dataset.run") == 'idle', 60, what='the node ending by itself')
    assert 'finished' in console(ide).split(said)[-1]
    if example == 'drive_square.json':      # sides of 3 m: the turtle went that far from where it started
        far = max(abs(m['x'] - before['x']) + abs(m['y'] - before['y']) for _, m in pose.messages)
        assert far > 2.5, far


def test_the_served_programs_node_answers_roslibpy(ide, turtle):
    ide.js('(p) => rosgateIde.loadProgram(p)', served_program())
    code = ide.js('async () => rosgateIde.rosNode()')
    load(ide, code, 'served')
    run(ide)
    check_served(turtle.ros, timeout=PYODIDE_START)
    logged(ide, 'its callbacks go on until Ctrl-C')
    stop(ide)


def test_stop_zeroes_what_a_node_drove(ide, turtle):
    cmd = turtle.watch('/turtle1/cmd_vel', TWIST)
    load(ide, '\n'.join([
        'import rclpy', 'from rclpy.node import Node', 'from geometry_msgs.msg import Twist', '',
        'rclpy.init()', "node = Node('circler')", "pub = node.create_publisher(Twist, 'turtle1/cmd_vel', 10)",
        'def tick():', '    msg = Twist()', '    msg.linear.x = 0.5', '    msg.angular.z = 1.0', '    pub.publish(msg)',
        'node.create_timer(0.05, tick)', 'rclpy.spin(node)']))
    run(ide)
    wait_for(lambda: any(m['linear']['x'] == 0.5 for _, m in cmd.messages), PYODIDE_START, what='the node drives')
    t0 = time.monotonic()
    stop(ide)
    zero = wait_for(lambda: next((t for t, m in cmd.since(t0) if m['linear']['x'] == 0 and m['angular']['z'] == 0), None),
                    what='a zero Twist after Stop')
    time.sleep(0.3)
    assert all(m['linear']['x'] == 0 for _, m in cmd.since(zero + 0.05)), 'the node drove on after Stop'


def ended(ide: IdePage):
    ide.page.wait_for_function("document.body.dataset.run === 'idle'", timeout=PYODIDE_START * 1000)


def test_mistakes_read_as_on_a_ros_machine(ide):
    load(ide, '\n'.join(['from geometry_msgs.msg import Twist', 'msg = Twist()', 'msg.linear.x = 1']))
    run(ide)
    ended(ide)
    assert error_line(ide) == 3
    assert "AssertionError: The 'x' field must be of type 'float'" in logged(ide, "must be of type 'float'")
    load(ide, 'from geometry_msgs.msg import NoSuchThing\n')
    run(ide)
    ended(ide)
    assert "cannot import name 'NoSuchThing' from 'geometry_msgs.msg'" in logged(ide, 'NoSuchThing')
    load(ide, 'import no_such_package_of_ros\n')
    run(ide)
    ended(ide)
    assert "No module named 'no_such_package_of_ros'" in logged(ide, "No module named 'no_such_package_of_ros'")


# procedures (one with a parameter, that waits), a handler and a timer that call it
PROCEDURES = json.loads(r"""{"format": "rosgate-program", "version": 1, "name": "procs", "robot": "turtlesim", "blocks": [], "workspace": {"blocks": {"languageVersion": 0, "blocks": [{"type": "procedures_defreturn", "x": 10, "y": 10, "extraState": {"params": [{"name": "n", "id": "var-n"}]}, "fields": {"NAME": "twice"}, "inputs": {"STACK": {"block": {"type": "ros_sleep", "inputs": {"SECONDS": {"shadow": {"type": "math_number", "fields": {"NUM": 0.1}}}}}}, "RETURN": {"block": {"type": "math_arithmetic", "fields": {"OP": "MULTIPLY"}, "inputs": {"A": {"block": {"type": "variables_get", "fields": {"VAR": {"id": "var-n"}}}}, "B": {"shadow": {"type": "math_number", "fields": {"NUM": 2}}}}}}}}, {"type": "ros_on_message", "x": 10, "y": 200, "fields": {"TOPIC": "/turtle1/pose", "TYPE": "turtlesim/msg/Pose", "VAR": {"id": "var-m"}}, "inputs": {"DO": {"block": {"type": "variables_set", "fields": {"VAR": {"id": "var-x"}}, "inputs": {"VALUE": {"block": {"type": "ros_field", "fields": {"FIELD": "x"}, "inputs": {"OBJ": {"block": {"type": "variables_get", "fields": {"VAR": {"id": "var-m"}}}}}}}}}}}}, {"type": "ros_every", "x": 10, "y": 300, "inputs": {"SECONDS": {"shadow": {"type": "math_number", "fields": {"NUM": 0.5}}}, "DO": {"block": {"type": "ros_log", "inputs": {"VALUE": {"block": {"type": "procedures_callreturn", "extraState": {"name": "twice", "params": ["n"]}, "inputs": {"ARG0": {"block": {"type": "variables_get", "fields": {"VAR": {"id": "var-x"}}}}}}}}}}}}, {"type": "ros_log", "x": 300, "y": 10, "inputs": {"VALUE": {"block": {"type": "procedures_callreturn", "extraState": {"name": "twice", "params": ["n"]}, "inputs": {"ARG0": {"shadow": {"type": "math_number", "fields": {"NUM": 21}}}}}}}}]}, "variables": [{"name": "n", "id": "var-n"}, {"name": "m", "id": "var-m"}, {"name": "x", "id": "var-x"}]}}""")


def test_a_node_whose_procedures_wait_runs(ide):
    """Procedures are the node's async methods (their parameters plain names); a timer whose
    callback waits is async in a group of its own; a message handler stores what it reads."""
    ide.js('(p) => rosgateIde.loadProgram(p)', PROCEDURES)
    code = ide.js('async () => rosgateIde.rosNode()')
    for line in ('    async def twice(self, n):', '        await self.sleep(0.1)', '        return n * 2',
                 "        self.get_logger().info(str(await self.twice(21)))",
                 '    async def every_tick(self):', 'callback_group=MutuallyExclusiveCallbackGroup())',
                 '        self.x = self.m.x'):
        assert line in code, (line, code)
    assert 'self.n = None' not in code            # a parameter is not the node's attribute
    load(ide, code, 'procedures')
    run(ide)
    text = logged(ide, '[procs]: 42')
    wait_for(lambda: console(ide).count('[procs]: ') >= 3, what='the timer calling the procedure')
    stop(ide)
    assert 'Traceback' not in text.split('▶ run')[-1]         # (an earlier run's may be above)


def test_a_node_in_the_page_obeys_the_gateways_rules(start_gateway, browser_ctx):
    """The page's rclpy sends the page's own ops: a topic the gateway's globs refuse is refused (the
    console says so, as a ROS error line), one they allow goes through."""
    gw = start_gateway('--robot', 'turtlesim', '--topics-glob', "['/turtle1/*', '/rosgate/*', '/client_count']")
    ide = page(browser_ctx, gw)
    load(ide, '\n'.join([
        'import rclpy', 'from rclpy.node import Node', 'from geometry_msgs.msg import Twist', '',
        'rclpy.init()', "node = Node('ruled')",
        "hidden = node.create_publisher(Twist, '/elsewhere/cmd_vel', 10)",
        "allowed = node.create_publisher(Twist, 'turtle1/cmd_vel', 10)",
        'msg = Twist()', 'msg.linear.x = 0.5',
        'def tick():', '    hidden.publish(msg)', '    allowed.publish(msg)',
        'node.create_timer(0.1, tick)', 'rclpy.spin(node)']))
    with client(gw) as ros:
        cmd = Inbox(ros, '/turtle1/cmd_vel', TWIST)
        run(ide)
        text = logged(ide, '[ERROR] [')
        assert '/elsewhere/cmd_vel' in text.split('[ERROR] [')[1].split('\n')[0], text[-1000:]
        cmd.wait(lambda m: m['linear']['x'] == 0.5, timeout=30)
        n = len(cmd.messages)      # ten more ticks, each publishing on both topics
        wait_for(lambda: len(cmd.messages) >= n + 10, 30, what='ten more publishes')
        refusals = [line for line in console(ide).split('\n') if line.startswith('[ERROR]') and '/elsewhere/cmd_vel' in line]
        assert 1 <= len(refusals) <= 2, refusals                  # its advertise and its publish, once each
        stop(ide)
