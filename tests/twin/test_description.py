"""The robot's description for the twin (GET /api/description, GET /urdf), with xacro: a --urdf in
xacro is expanded at start-up ($(find PKG) through --mesh-path), a robot_description topic in
xacro is expanded when asked, a robot without a description gets an answer and not a 404, and a
xacro from the graph cannot read a file outside the robot's packages nor the gateway's environment.
Gateways are real processes; the robot's topics are published through roslibpy."""

from __future__ import annotations

import subprocess
import sys

import pytest
import roslibpy

from tests.support.http import api, http
from tests.support.process import ROOT
from tests.support.ros import client
from tests.support.wait import wait_for

PARTS = """<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="wheel" params="side y">
    <link name="${side}_wheel_link"><visual><geometry><cylinder radius="${r}" length="0.02"/></geometry></visual></link>
    <joint name="${side}_wheel_joint" type="continuous"><parent link="base_link"/><child link="${side}_wheel_link"/>
      <origin xyz="0 ${y} 0"/></joint>
  </xacro:macro>
</robot>"""
ROBOT = """<?xml version="1.0"?>
<robot name="NAME" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:property name="r" value="${0.05 * 2}"/>
  <xacro:include filename="$(find xbot_description)/urdf/parts.xacro"/>
  <link name="base_link"><visual><geometry><mesh filename="package://xbot_description/meshes/body.stl"/></geometry>
  </visual></link>
  <xacro:wheel side="left" y="0.1"/>
  <xacro:wheel side="right" y="-0.1"/>
</robot>"""


def xacro(name: str) -> str:
    return ROBOT.replace('NAME', name)


@pytest.fixture(scope='module')
def packages(tmp_path_factory):
    top = tmp_path_factory.mktemp('xacro')
    urdf = top / 'pkgs' / 'xbot_description' / 'urdf'
    urdf.mkdir(parents=True)
    (urdf / 'parts.xacro').write_text(PARTS)
    (top / 'robot.urdf.xacro').write_text(xacro('from_file'))
    (top / 'secret.xml').write_text('<robot name="secret"/>')
    return top


@pytest.fixture(scope='module')
def graph(launch, packages):
    """A gateway without --urdf: descriptions come from the graph."""
    return launch('--robot', 'rover', '--mesh-path', str(packages / 'pkgs'))


def expanded(text: str, name: str) -> None:
    assert f'<robot name="{name}">' in text and 'xacro' not in text, text[:300]
    assert '<cylinder length="0.02" radius="0.1"/>' in text and 'right_wheel_joint' in text, text[:800]
    assert 'package://xbot_description/meshes/body.stl' in text


def test_a_xacro_urdf_file_is_expanded(launch, packages):
    gw = launch('--robot', 'none', '--urdf', str(packages / 'robot.urdf.xacro'), '--mesh-path', str(packages / 'pkgs'))
    status, body = api(gw, 'GET', '/api/description')
    assert status == 200 and body['from'] == '--urdf', body
    expanded(body['urdf'], 'from_file')
    reply = http(gw, '/urdf')
    assert reply.status == 200 and reply.headers['Content-Type'].startswith('text/xml')
    expanded(reply.body.decode(), 'from_file')


def test_a_xacro_urdf_that_does_not_expand_stops_the_start(packages, tmp_path):
    bad = tmp_path / 'bad.xacro'
    bad.write_text(xacro('bad').replace('xbot_description', 'no_such_package'))
    done = subprocess.run([sys.executable, '-m', 'gateway', '--port', '0', '--robot', 'none', '--urdf', str(bad),
                           '--mesh-path', str(packages / 'pkgs')], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done
    assert '--urdf' in done.stderr and 'no_such_package' in done.stderr, done.stderr


def test_the_start_line_names_the_twin(graph):
    assert f'twin {graph.http_url}twin ' in graph.line, graph.line


def test_the_sims_rover_description_comes_from_its_topic(graph):
    status, body = api(graph, 'GET', '/api/description')
    assert status == 200 and body['from'] == 'topic' and '<robot' in body['urdf'], body


def test_a_robot_without_a_description_is_an_answer_not_a_404(graph):
    status, body = api(graph, 'GET', '/api/description?ns=/nobody')
    assert (status, body) == (200, {'urdf': '', 'from': None})
    assert http(graph, '/urdf').status == 404          # no --urdf: for tools that ask; the pages do not
    status, body = api(graph, 'GET', '/api/description?ns=/a%20b')
    assert status == 400 and '"ns"' in body['error'], body


def test_a_xacro_on_the_robot_description_topic_is_expanded(graph):
    with client(graph) as ros:
        topic = roslibpy.Topic(ros, '/xbot/robot_description', 'std_msgs/msg/String', latch=True)
        topic.advertise()
        topic.publish(roslibpy.Message({'data': xacro('from_topic')}))
        body = wait_for(lambda: (r := api(graph, 'GET', '/api/description?ns=/xbot')[1]).get('from') and r,
                        what='the description from the topic')
        assert body['from'] == 'topic', body
        expanded(body['urdf'], 'from_topic')
        # a newer one replaces it (the expansions are kept by their text)
        topic.publish(roslibpy.Message({'data': xacro('newer')}))
        wait_for(lambda: '<robot name="newer">' in api(graph, 'GET', '/api/description?ns=/xbot')[1]['urdf'],
                 what='the newer description')
        topic.unadvertise()


@pytest.mark.parametrize('n, bad, why', [
    (1, '<xacro:include filename="SECRET"/>', 'outside the robot'),     # a file beside, not a package's
    (2, '<xacro:include filename="/etc/hostname"/>', 'outside the robot'),
    (3, '<xacro:property name="home" value="$(env HOME)"/><link name="${home}"/>', 'HOME'),
    (4, '<link name="${().__class__}"/>', 'invalid name'),
])
def test_a_xacro_from_the_graph_reads_nothing_outside_the_robots_packages(graph, packages, n, bad, why):
    text = ('<robot name="evil" xmlns:xacro="http://www.ros.org/wiki/xacro">'
            + bad.replace('SECRET', str(packages / 'secret.xml')) + '</robot>')
    with client(graph) as ros:
        topic = roslibpy.Topic(ros, f'/evil{n}/robot_description', 'std_msgs/msg/String', latch=True)
        topic.advertise()
        topic.publish(roslibpy.Message({'data': text}))
        status, body = wait_for(lambda: (r := api(graph, 'GET', f'/api/description?ns=/evil{n}'))[1].get('error') and r,
                                what='the refusal')
        assert status == 502 and why in body['error'], body
        assert 'name="secret"' not in body['error'] and 'urdf' not in body, body
        topic.unadvertise()
