"""The IDE's ROS 2 package download (.zip) in Chromium: the ament_python package of an example
program, as the file PROGRAM.zip; the node in the code panel. (That it builds with colcon and drives
a robot on the Jazzy graph is tests/backends/test_ros_package.py, in make test-rclpy.)"""

from __future__ import annotations

import ast
import io
import zipfile
from pathlib import Path

import pytest


@pytest.fixture(scope='module')
def gw(start_gateway):
    return start_gateway('--robot', 'turtlesim')


def download(ide, example: str) -> tuple[str, zipfile.ZipFile]:
    ide.load_example(example)
    ide.page.click("[data-tab='code-node']")
    assert ide.page.is_visible('#code-node')
    with ide.page.expect_download() as d:
        ide.page.click('#download-ros2')
    return d.value.suggested_filename, zipfile.ZipFile(io.BytesIO(Path(d.value.path()).read_bytes()))


@pytest.mark.parametrize('example, name, deps, declared', [
    ('drive_square.json', 'drive a square', ['geometry_msgs', 'rclpy', 'turtlesim'],
     ["self.service_client('turtle1/set_pen', SetPen)", "self.publisher('turtle1/cmd_vel', Twist)",
      "self.subscription('turtle1/pose', Pose)"]),
    ('fibonacci.json', None, ['example_interfaces', 'rclpy'], ["self.action_client('/fibonacci', Fibonacci)"]),
])
def test_the_package_of_an_example(gw, ide_factory, example, name, deps, declared):
    ide = ide_factory(gw, accept_downloads=True)
    filename, archive = download(ide, example)
    program = ide.js('rosgateIde.programName')
    assert filename == f'{program}.zip' and (name is None or program == name)
    pkg = archive.namelist()[0].split('/')[0]
    node = f'{pkg}_node'
    files = set(archive.namelist())
    assert {f'{pkg}/package.xml', f'{pkg}/setup.py', f'{pkg}/setup.cfg', f'{pkg}/resource/{pkg}', f'{pkg}/README.md',
            f'{pkg}/{pkg}/__init__.py', f'{pkg}/{pkg}/{node}.py', f'{pkg}/{pkg}/rosgate_node.py',
            f'{pkg}/{pkg}/rosgate_runtime.py'} <= files, files
    xml = archive.read(f'{pkg}/package.xml').decode()
    assert [line.strip()[len('<exec_depend>'):-len('</exec_depend>')] for line in xml.splitlines()
            if '<exec_depend>' in line] == deps
    assert '<build_type>ament_python</build_type>' in xml and f'<name>{pkg}</name>' in xml
    setup = archive.read(f'{pkg}/setup.py').decode()
    assert f'"{node} = {pkg}.{node}:main"' in setup
    assert f'install_scripts=$base/lib/{pkg}' in archive.read(f'{pkg}/setup.cfg').decode()
    code = archive.read(f'{pkg}/{pkg}/{node}.py').decode()
    ast.parse(code)
    for module in ('rosgate_node.py', 'rosgate_runtime.py'):
        ast.parse(archive.read(f'{pkg}/{pkg}/{module}').decode())
    assert code == ide.js("document.querySelector('#code-node').textContent")
    for line in declared:
        assert line in code, code
    assert 'class ' in code and '(BlockNode):' in code and 'def program(self):' in code
    assert 'raise SystemExit(run_node(' in code
    assert 'colcon build' in archive.read(f'{pkg}/README.md').decode()
    assert not ide.errors, ide.errors
