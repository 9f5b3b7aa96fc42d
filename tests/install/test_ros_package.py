"""ROS 2 users: package.xml is a valid format 3 ament_python manifest that agrees with
pyproject.toml, `colcon build` in a workspace holding the package installs what `ros2 launch` and
`ros2 run` look for, and the launch file takes rosbridge_websocket_launch.xml's arguments and
turns them into a command line rosgate accepts."""

from __future__ import annotations

import json
import re
import shutil
import tomllib
import urllib.request
import xml.etree.ElementTree as ET

import pytest

from tests.support.install import run, started
from tests.support.process import ROOT

# rosbridge_server's launch/rosbridge_websocket_launch.xml (ros2 branch): its arguments.
ROSBRIDGE_ARGS = {
    'port', 'address', 'url_path', 'ssl', 'certfile', 'keyfile', 'retry_startup_delay', 'fragment_timeout',
    'delay_between_messages', 'max_message_size', 'unregister_timeout', 'use_compression',
    'call_services_in_new_thread', 'send_action_goals_in_new_thread', 'topics_glob', 'services_glob',
    'params_glob', 'bson_only_mode', 'binary_encoder',
}
# Accepted so that rosbridge command lines work, with no effect (the launch file says why).
NO_EFFECT = {'retry_startup_delay', 'delay_between_messages', 'call_services_in_new_thread',
             'send_action_goals_in_new_thread', 'bson_only_mode', 'binary_encoder'}
LAUNCH = ROOT / 'launch' / 'rosgate_launch.xml'
PAIR = re.compile(r'(\w+):=\$\(var (\w+)\)')


def test_package_xml_is_format_3_ament_python_and_agrees_with_pyproject(tools):
    """catkin_pkg (what colcon-ros reads manifests with) parses and validates it."""
    script = ('import json, sys; from catkin_pkg.package import parse_package; p = parse_package(sys.argv[1]); '
              'p.validate(); print(json.dumps({"name": p.name, "version": p.version, "format": p.package_format, '
              '"description": p.description, "licenses": [str(x) for x in p.licenses], '
              '"build_type": p.get_build_type(), "exec": [d.name for d in p.exec_depends]}))')
    info = json.loads(run([tools, '-c', script, ROOT / 'package.xml']).stdout)
    project = tomllib.loads((ROOT / 'pyproject.toml').read_text())['project']
    assert info['format'] == 3 and info['build_type'] == 'ament_python'
    assert (info['name'], info['version'], info['description']) == \
        (project['name'], project['version'], project['description'])
    assert info['licenses'] == [project['license']]   # an SPDX expression (PEP 639)
    assert {'rclpy', 'std_msgs', 'geometry_msgs', 'sensor_msgs'} <= set(info['exec'])


def launch_args() -> dict[str, str]:
    return {a.get('name'): a.get('default') for a in ET.parse(LAUNCH).getroot().iter('arg')}


def node_command_lines() -> dict[str, str]:
    """The node's args per branch of the ssl group ('true', 'false')."""
    root = ET.parse(LAUNCH).getroot()
    lines = {}
    for group in root.iter('group'):
        branch = 'true' if group.get('if') == '$(var ssl)' else 'false' if group.get('unless') == '$(var ssl)' else None
        (node,) = group.iter('node')
        assert (node.get('pkg'), node.get('exec')) == ('rosgate', 'rosgate')
        lines[branch] = node.get('args')
    assert set(lines) == {'true', 'false'}
    return lines


def argv_for(line: str, values: dict[str, str]) -> list[str]:
    """As launch does: each `key:=$(var name)` is one argument, whatever the value holds."""
    assert PAIR.sub('', line).split() == [], 'only key:=$(var name) pairs in args'
    return [f'{key}:={values[name]}' for key, name in PAIR.findall(line)]


def test_launch_file_takes_rosbridge_arguments_and_rosgate_understands_them():
    from gateway.cli import build_parser, ros_style, settings_from
    args = launch_args()
    assert ROSBRIDGE_ARGS <= set(args)
    lines = node_command_lines()
    used = {name for line in lines.values() for _, name in PAIR.findall(line)}
    assert set(args) - used == NO_EFFECT | {'ssl'}, 'every argument reaches rosgate or is documented as no effect'
    for line in lines.values():
        assert all(key == name for key, name in PAIR.findall(line))
    parser = build_parser()
    flags = set(parser._option_string_actions)
    assert {'--' + name.replace('_', '-') for name in used} <= flags

    # ros2 launch rosgate rosgate_launch.xml port:=9091 (the defaults for the rest)
    plain = parser.parse_args(ros_style(argv_for(lines['false'], {**args, 'port': '9091'}), parser))
    assert (plain.port, plain.address, plain.certfile, plain.use_compression) == (9091, '', None, False)
    settings = settings_from(plain)
    assert plain.topics_glob == '' and settings.safety.stop_on_disconnect is True
    assert settings.safety.exclusive_control is False
    # ssl:=true with a certificate; rosbridge-style booleans and globs
    tls = parser.parse_args(ros_style(argv_for(lines['true'], {
        **args, 'ssl': 'true', 'certfile': '/etc/c.pem', 'keyfile': '/etc/k.pem', 'use_compression': 'true',
        'topics_glob': "['/turtle1/*', '/rosout']"}), parser))
    assert (tls.certfile, tls.keyfile, tls.use_compression) == ('/etc/c.pem', '/etc/k.pem', True)
    assert tls.topics_glob == "['/turtle1/*', '/rosout']"


@pytest.fixture(scope='module')
def colcon_install(tools, sdist_tree, tmp_path_factory):
    """`colcon build` in a workspace whose src/ holds the package."""
    ws = tmp_path_factory.mktemp('ws')
    shutil.copytree(sdist_tree, ws / 'src' / 'rosgate')
    run([tools.parent / 'colcon', 'build'], cwd=ws)
    return ws / 'install' / 'rosgate'


def test_colcon_build_installs_what_ros2_looks_for(colcon_install):
    assert (colcon_install / 'share/ament_index/resource_index/packages/rosgate').is_file()
    assert (colcon_install / 'share/rosgate/package.xml').read_text() == (ROOT / 'package.xml').read_text()
    assert (colcon_install / 'share/rosgate/launch/rosgate_launch.xml').is_file()
    assert (colcon_install / 'lib/rosgate/rosgate').is_file()   # where `ros2 run` and <node exec=...> look
    (site,) = colcon_install.glob('lib/python3*/site-packages')
    assert (site / 'gateway/_assets/ide/vendor/roslib.mjs').is_file()


def test_colcon_installed_gateway_serves_the_ide(colcon_install, user_venv, tmp_path):
    """What `source install/setup.bash && ros2 run rosgate rosgate port:=...` runs (the interpreter
    of the clean venv supplies the Python dependencies, as the system's would)."""
    (site,) = colcon_install.glob('lib/python3*/site-packages')
    env = {'PYTHONPATH': str(site), 'AMENT_PREFIX_PATH': str(colcon_install)}
    where = run([user_venv, '-c', 'import gateway; print(gateway.__file__)'], cwd=tmp_path, env=env).stdout
    assert where.startswith(str(site))
    gw = started([user_venv, colcon_install / 'lib/rosgate/rosgate', 'port:=0', 'address:=127.0.0.1',
                  'backend:=sim', 'use_compression:=false', f'programs_dir:={tmp_path / "programs"}'],
                 cwd=tmp_path, env=env)
    try:
        assert 'IDE http://127.0.0.1:' in gw.line
        with urllib.request.urlopen(gw.http_url, timeout=10) as r:
            assert b'vendor/blockly/blockly_compressed.js' in r.read()
    finally:
        gw.stop()


def test_colcon_symlink_install_serves_the_source_tree(tools, sdist_tree, user_venv, tmp_path):
    """`colcon build --symlink-install`: Python files and the IDE come from the workspace's source."""
    ws = tmp_path / 'ws'
    shutil.copytree(sdist_tree, ws / 'src' / 'rosgate')
    run([tools.parent / 'colcon', 'build', '--symlink-install'], cwd=ws)
    install = ws / 'install' / 'rosgate'
    assert (install / 'share/rosgate/launch/rosgate_launch.xml').resolve() == \
        (ws / 'src/rosgate/launch/rosgate_launch.xml').resolve()
    env = {'PYTHONPATH': str(ws / 'build' / 'rosgate'), 'AMENT_PREFIX_PATH': str(install)}   # colcon's hook
    script = 'import gateway.settings as a; print(a.ide_dir().resolve())'
    assert run([user_venv, '-c', script], cwd=tmp_path, env=env).stdout.strip() == str((ws / 'src/rosgate/ide').resolve())
    gw = started([user_venv, install / 'lib/rosgate/rosgate', 'port:=0', 'address:=127.0.0.1', 'backend:=sim',
                  f'programs_dir:={tmp_path / "programs"}'], cwd=tmp_path, env=env)
    try:
        with urllib.request.urlopen(gw.http_url + 'teleop', timeout=10) as r:
            assert r.status == 200
    finally:
        gw.stop()
