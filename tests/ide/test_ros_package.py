"""The IDE's ROS 2 packages in Chromium: "ROS 2 package (.zip)" of the program shown (an example's
blocks: its node is plain rclpy, as the code panel shows it; a Python text program typed into the
editor: that text, not the block program open before it), and a package of several library
programs (one entry point each, a launch file starting them). That the packages build with colcon
and drive a robot on the Jazzy graph is tests/backends/test_ros_package.py (make test-rclpy); that
every example's node runs in the page is tests/ide/test_rclpy_page.py."""

from __future__ import annotations

import ast
import io
import json
import zipfile
from pathlib import Path

import pytest

from tests.support.ide import EXAMPLES, open_text
from tests.support.wait import wait_for

from .test_text_python import type_python


@pytest.fixture(scope='module')
def gw(start_gateway):
    return start_gateway('--robot', 'turtlesim')


def download(ide, selector: str = '#download-ros2') -> tuple[str, zipfile.ZipFile]:
    with ide.page.expect_download() as d:
        ide.page.click(selector)
    return d.value.suggested_filename, zipfile.ZipFile(io.BytesIO(Path(d.value.path()).read_bytes()))


def deps(archive, pkg) -> list[str]:
    xml = archive.read(f'{pkg}/package.xml').decode()
    assert '<build_type>ament_python</build_type>' in xml and f'<name>{pkg}</name>' in xml
    return [line.strip()[len('<exec_depend>'):-len('</exec_depend>')] for line in xml.splitlines() if '<exec_depend>' in line]


def check_node(code: str, cls: str, node_name: str):
    """Plain rclpy a ROS teacher would write: a Node subclass made with its name, the types it uses
    imported as ROS names them, no star import, no runtime object, main() spins it."""
    tree = ast.parse(code)
    imports = [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert not [n for n in imports if any(a.name == '*' for a in n.names)], 'a star import'
    assert not [n for n in imports if n.module and 'rosgate' in n.module], 'an import of a rosgate runtime'
    assert not any(a.asname for n in imports for a in n.names), 'an import renamed'
    assert 'rt.' not in code and 'rt =' not in code
    classes = {n.name: n for n in tree.body if isinstance(n, ast.ClassDef)}
    assert [b.id for b in classes[cls].bases] == ['Node']
    assert f"super().__init__('{node_name}')" in code
    assert 'def main(args=None):' in code and 'rclpy.init(args=args' in code and 'executor.spin_once(' in code
    assert "if __name__ == '__main__':" in code


@pytest.mark.parametrize('example, pkg, cls, deps_, lines', [
    ('drive_square.json', 'drive_a_square', 'DriveASquare', ['geometry_msgs', 'rclpy', 'turtlesim'],
     ["self.cmd_vel_pub = self.create_publisher(Twist, 'turtle1/cmd_vel', 10)",
      "self.create_subscription(Pose, 'turtle1/pose', self.on_pose, 10)",
      "self.set_pen_client = self.create_client(SetPen, 'turtle1/set_pen')",
      'await self.call(self.set_pen_client, SetPen.Request(r=255, g=220, b=0, width=4, off=0))',
      'await self.move(self.cmd_vel_pub, lambda: self.pose, 3.0, 2.0)',
      "self.get_logger().info('square done')", 'from geometry_msgs.msg import Twist']),
    ('wall_follower.json', 'rover_wall_follower', 'RoverWallFollower', ['geometry_msgs', 'rclpy', 'sensor_msgs'],
     ["self.cmd_vel_pub = self.create_publisher(Twist, 'cmd_vel', 10)", 'msg = Twist()',
      'msg.linear.x = 0.3', 'msg.angular.z = math.radians(25)', 'self.cmd_vel_pub.publish(msg)',
      'self.ahead = range_at(self.scan, 0, 30)', 'await self.sleep(0.1)']),
    ('fibonacci.json', 'fibonacci_action_with_feedback', 'FibonacciActionWithFeedback',
     ['action_msgs', 'example_interfaces', 'rclpy'],
     ["self.fibonacci_client = ActionClient(self, Fibonacci, '/fibonacci')",
      'self.result = await self.send_goal(self.fibonacci_client, Fibonacci.Goal(order=8), self.on_feedback)',
      'goal_handle = await client.send_goal_async(goal, feedback_callback=feedback)']),
])
def test_the_package_of_an_example_is_a_plain_rclpy_node(gw, ide_factory, example, pkg, cls, deps_, lines):
    ide = ide_factory(gw, accept_downloads=True)
    ide.load_example(example)
    ide.page.click("[data-tab='code-node']")
    filename, archive = download(ide)
    assert filename == f"{ide.js('rosgateIde.programName')}.zip"
    files = set(archive.namelist())
    assert {f'{pkg}/package.xml', f'{pkg}/setup.py', f'{pkg}/setup.cfg', f'{pkg}/resource/{pkg}', f'{pkg}/README.md',
            f'{pkg}/{pkg}/__init__.py', f'{pkg}/{pkg}/{pkg}.py'} == files, files     # no runtime beside it
    assert deps(archive, pkg) == deps_
    assert f'"{pkg} = {pkg}.{pkg}:main"' in archive.read(f'{pkg}/setup.py').decode()
    assert f'install_scripts=$base/lib/{pkg}' in archive.read(f'{pkg}/setup.cfg').decode()
    code = archive.read(f'{pkg}/{pkg}/{pkg}.py').decode()
    check_node(code, cls, pkg)
    for line in lines:
        assert line in code, (line, code)
    # the code panel shows the node the package carries (once the gateway's types are read)
    wait_for(lambda: ide.js("document.querySelector('#code-node').textContent") == code, what='the panel shows the node')
    assert f'ros2 run {pkg} {pkg}' in archive.read(f'{pkg}/README.md').decode()
    assert not ide.errors, ide.errors


def test_the_package_of_a_typed_text_program_is_that_program(gw, ide_factory):
    """After a block program (drive a square), a Python program typed into the editor: its package
    holds the typed text (an rclpy node: its main() the entry point), not the blocks."""
    ide = ide_factory(gw, accept_downloads=True)
    ide.load_example('drive_square.json')
    open_text(ide, 'python')
    lines = ['import rclpy', 'from rclpy.node import Node', 'from std_msgs.msg import String', '',
             'def main():', "    rclpy.init()", "    node = Node('typed')", "    pub = node.create_publisher(String, 'chatter', 10)",
             "    pub.publish(String(data='hi'))", '    rclpy.shutdown()', '', "if __name__ == '__main__':", '    main()']
    type_python(ide, lines)
    ide.js("rosgateIde.programName = 'typed talker'")
    filename, archive = download(ide)
    assert filename == 'typed talker.zip'
    assert archive.read('typed_talker/typed_talker/typed_talker.py').decode() == '\n'.join(lines)
    assert deps(archive, 'typed_talker') == ['rclpy', 'std_msgs']
    assert '"typed_talker = typed_talker.typed_talker:main"' in archive.read('typed_talker/setup.py').decode()
    text = '\n'.join(archive.read(n).decode() for n in archive.namelist())
    assert 'SetPen' not in text and 'set_pen' not in text          # nothing of the block program before it
    # a roslibpy program of top-level lines: the runtime on its import line, run as a script
    type_python(ide, ['from rosgate_runtime import *', "rt.log('hello')"])
    _, archive = download(ide)
    files = archive.namelist()
    assert 'typed_talker/typed_talker/typed_talker_main.py' in files
    program = archive.read('typed_talker/typed_talker/typed_talker.py').decode()
    assert program.splitlines()[0].endswith('from rosgate_runtime import *') and 'class Runtime' in program
    assert '"typed_talker = typed_talker.typed_talker_main:main"' in archive.read('typed_talker/setup.py').decode()
    assert 'pip install roslibpy' in archive.read('typed_talker/README.md').decode()
    assert not ide.errors, ide.errors


def test_a_package_of_several_library_programs_has_a_launch_file(gw, ide_factory):
    ide = ide_factory(gw, accept_downloads=True)
    names = []
    for example in ('drive_square.json', 'spiral.json'):
        program = json.loads((EXAMPLES / example).read_text())
        ide.js('(p) => rosgateIde.loadProgram(p)', program)
        ide.page.fill('#name', program['name'] + ' kept')
        ide.page.dispatch_event('#name', 'change')
        ide.page.click('#library')
        ide.page.click('#library-save')
        names.append(program['name'] + ' kept')
        ide.page.click('#library-close')
    ide.page.click('#library')
    for name in names:
        ide.page.check(f"#library-list li[data-name='{name}'] input.lib-pick")
    _, archive = download(ide, '#library-package')
    pkg = 'rosgate_programs'
    exes = ['drive_a_square_kept', 'spiral_with_the_pen_kept']
    files = set(archive.namelist())
    assert {f'{pkg}/{pkg}/{e}.py' for e in exes} <= files and f'{pkg}/launch/{pkg}.launch.py' in files, files
    setup = archive.read(f'{pkg}/setup.py').decode()
    for e in exes:
        assert f'"{e} = {pkg}.{e}:main"' in setup
        check_node(archive.read(f'{pkg}/{pkg}/{e}.py').decode(), ''.join(w.title() for w in e.split('_')), e)
    assert 'glob("launch/*.launch.py")' in setup
    launch = archive.read(f'{pkg}/launch/{pkg}.launch.py').decode()
    ast.parse(launch)
    for e in exes:
        assert f'Node(package="{pkg}", executable="{e}"' in launch
    assert deps(archive, pkg) == ['geometry_msgs', 'launch', 'launch_ros', 'rclpy', 'turtlesim']
    assert not ide.errors, ide.errors
