"""/twin with a robot whose robot_description is xacro (in Chromium): the gateway expands it, with
$(find PKG) through --mesh-path, and the twin draws its links and joints; a new xacro published
on the topic replaces the model. No request of the page fails."""

from __future__ import annotations

import pytest
import roslibpy

from tests.support.ide import TABLET
from tests.support.ros import client

PARTS = """<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="wheel" params="side y">
    <link name="${side}_wheel_link"><visual><geometry><cylinder radius="${r}" length="0.04"/></geometry>
      <material name="black"><color rgba="0.1 0.1 0.1 1"/></material></visual></link>
    <joint name="${side}_wheel_joint" type="continuous"><parent link="base_link"/><child link="${side}_wheel_link"/>
      <origin xyz="0 ${y} 0" rpy="1.5708 0 0"/><axis xyz="0 0 1"/></joint>
  </xacro:macro>
</robot>"""
ROBOT = """<?xml version="1.0"?>
<robot name="NAME" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:property name="r" value="${0.05 * 2}"/>
  <xacro:include filename="$(find xbot_description)/urdf/parts.xacro"/>
  <link name="base_link"><visual><geometry><box size="0.4 0.3 0.1"/></geometry>
    <material name="orange"><color rgba="1 0.5 0 1"/></material></visual></link>
  <xacro:wheel side="left" y="0.18"/>
  <xacro:wheel side="right" y="-0.18"/>
</robot>"""


@pytest.fixture(scope='module')
def xbot(launch, tmp_path_factory):
    top = tmp_path_factory.mktemp('xbot')
    (top / 'pkgs' / 'xbot_description' / 'urdf').mkdir(parents=True)
    (top / 'pkgs' / 'xbot_description' / 'urdf' / 'parts.xacro').write_text(PARTS)
    return launch('--robot', 'none', '--mesh-path', str(top / 'pkgs'))


def test_the_twin_draws_a_xacro_description_and_follows_a_new_one(xbot, chromium):
    gw = xbot
    with client(gw) as ros:
        topic = roslibpy.Topic(ros, '/xbot/robot_description', 'std_msgs/msg/String', latch=True)
        topic.advertise()
        topic.publish(roslibpy.Message({'data': ROBOT.replace('NAME', 'xbot')}))
        ctx = chromium.new_context(viewport=TABLET)
        try:
            page = ctx.new_page()
            problems = []
            page.on('pageerror', lambda e: problems.append(str(e)))
            page.on('console', lambda m: m.type == 'error' and problems.append(m.text))
            page.on('response', lambda r: r.status >= 400 and problems.append(f'{r.status} {r.url}'))
            page.goto(gw.http_url + 'twin?ns=/xbot')
            page.wait_for_function("document.body.dataset.ready === 'true'", timeout=60000)
            if page.evaluate("!!document.querySelector('#view').dataset.webgl"):
                pytest.skip('no WebGL here')
            page.wait_for_function("twin.state.model === 'urdf' && twin.model.robot.robotName === 'xbot'", timeout=60000)
            assert page.evaluate('twin.state.urdfFrom') == 'topic'
            joints = page.evaluate('Object.keys(twin.model.robot.joints).sort()')
            assert joints == ['left_wheel_joint', 'right_wheel_joint'], joints
            urdf = page.evaluate('twin.state.urdfText')
            assert '<cylinder length="0.04" radius="0.1"/>' in urdf and 'xacro' not in urdf   # ${0.05 * 2}, expanded
            # a new description on the topic (xacro again): the twin asks the gateway and redraws
            topic.publish(roslibpy.Message({'data': ROBOT.replace('NAME', 'xbot2')}))
            page.wait_for_function("twin.model.robot.robotName === 'xbot2'", timeout=30000)
            assert not problems, problems
        finally:
            ctx.close()
            topic.unadvertise()
