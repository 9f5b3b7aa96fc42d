"""/twin with a robot's own description, in Chromium's software WebGL: a robot in namespace /bot
(published here through the gateway, as a robot_state_publisher and a map server would) whose
URDF names an STL body, a Collada wheel and an OBJ mast of the package ``testbot`` (written by the test, found
by --mesh-path) and a mesh that does not exist. The meshes draw with their materials, the wheel's
pixels move with its joint state, TF places the robot, the map draws under it, and the missing
mesh is a grey box with a notice."""

from __future__ import annotations

import math
from contextlib import contextmanager

import pytest
import roslibpy

from tests.support.rawclient import Raw
from tests.support.ros import client

from tests.support.ide import ARTIFACTS, TABLET
from tests.support.testbot import joint_state, occupancy_grid, transform, write_package

WAIT = 60000
PIXEL_POLL = 250   # ms between reads of the whole canvas (each is a full readPixels)
MASKS = """() => {
  const gl = twin.renderer.getContext();
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
  const px = new Uint8Array(w * h * 4);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
  const orange = [], green = [];
  let floor = 0, blue = 0;
  for (let i = 0; i < w * h; i++) {
    const r = px[i * 4], g = px[i * 4 + 1], b = px[i * 4 + 2];
    if (r > 150 && g < 150 && b < 90 && r - g > 60) orange.push(i);
    else if (g > 120 && r < 110 && b < 110) green.push(i);
    else if (b > 150 && r < 90 && g < 140) blue++;
    else if (r > 170 && g > 170 && b > 170 && Math.abs(r - b) < 40) floor++;
  }
  return { orange, green, floor, blue };   // the pixels of the body and the wheel; the floor's and mast's counted
}"""


def open_page(page, url: str):
    """Go to the page at url and wait for its module to have run: it awaits the page's language
    first, so it may run after the load event goto waits for."""
    page.goto(url)
    page.wait_for_function("document.body?.dataset.ready === 'true' && !!(window.twin || window.teleop)", timeout=WAIT)


@contextmanager
def tablet_page(chromium, url: str | None = None):
    """(page, its errors) of a tablet-sized page (at url, when given); closed after."""
    ctx = chromium.new_context(viewport=TABLET)
    page = ctx.new_page()
    errors = []
    page.on('pageerror', lambda e: errors.append(str(e)))
    try:
        if url:
            open_page(page, url)
        yield page, errors
    finally:
        ctx.close()


@pytest.fixture(scope='module')
def bot(start_gateway, tmp_path_factory):
    meshes = write_package(tmp_path_factory.mktemp('mesh-path'))
    gw = start_gateway('--robot', 'none', '--mesh-path', str(meshes))
    with client(gw) as ros:
        def topic(name, type_, latch=False):
            t = roslibpy.Topic(ros, f'/bot/{name}', type_, latch=latch)
            t.advertise()
            return t
        description = topic('robot_description', 'std_msgs/msg/String', latch=True)
        description.publish(roslibpy.Message({'data': (meshes / 'testbot' / 'urdf' / 'testbot.urdf').read_text()}))
        static = topic('tf_static', 'tf2_msgs/msg/TFMessage', latch=True)
        static.publish(roslibpy.Message({'transforms': [transform('map', 'bot/odom'),
                                                        transform('bot/odom', 'bot/base_link', 0.5, 0.0, 0.0)]}))
        grid = topic('map', 'nav_msgs/msg/OccupancyGrid', latch=True)
        grid.publish(roslibpy.Message(occupancy_grid()))
        joints = topic('joint_states', 'sensor_msgs/msg/JointState')
        with Raw(gw.ws_url) as nav:   # the robot's navigation: a NavigateToPose action server
            nav.send({'op': 'advertise_action', 'action': '/bot/navigate_to_pose',
                      'type': 'nav2_msgs/action/NavigateToPose'})
            nav.wait_listed('/rosapi/action_servers', 'action_servers', '/bot/navigate_to_pose', 10)
            gw.nav = nav
            yield gw, joints


def test_the_robots_own_meshes_draw_and_its_wheel_turns(chromium, bot):
    gw, joints = bot
    joints.publish(roslibpy.Message(joint_state(0.0)))
    with tablet_page(chromium, gw.http_url + 'twin?ns=/bot') as (page, errors):
        page.wait_for_function("document.body.dataset.ready === 'true' && !!window.twin", timeout=WAIT)
        page.wait_for_function("twin.state.model === 'urdf' && twin.state.meshes === 'missing'", timeout=WAIT)
        assert page.evaluate('twin.state.urdfFrom') == 'topic'
        missing = page.evaluate('twin.state.missing')
        assert missing == ['package://testbot/meshes/missing.stl'], missing
        notice = page.text_content('#notice')
        assert 'missing.stl' in notice and 'grey box' in notice and page.is_visible('#notice')
        # the missing mesh is its link's collision box, 12 cm
        size = page.evaluate("""() => { let p = null;
          twin.robot.traverse((o) => { if (o.userData.placeholder) p = o.geometry.parameters; }); return p; }""")
        assert size == {'width': 0.12, 'height': 0.12, 'depth': 0.12, 'widthSegments': 1, 'heightSegments': 1,
                        'depthSegments': 1}, size
        # TF: map -> bot/odom -> bot/base_link at x = 0.5
        page.wait_for_function('twin.state.tf && Math.abs(twin.robot.position.x - 0.5) < 1e-6', timeout=WAIT)
        # the map, made to measure by the gateway (300 cells fit in 512: as it is)
        page.wait_for_function("twin.state.map && twin.state.map.width === 300", timeout=WAIT)

        joints.publish(roslibpy.Message(joint_state(0.0)))
        page.wait_for_function('twin.state.joints > 0', timeout=WAIT)
        page.wait_for_function(f'((m) => m.orange.length > 500 && m.green.length > 200)(({MASKS})())',
                               timeout=WAIT, polling=PIXEL_POLL)
        page.evaluate('twin.controls.update()')
        before = page.evaluate(MASKS)
        assert before['floor'] > 5000, before['floor']        # the map's free floor
        assert before['blue'] > 100, before['blue']           # the OBJ mast in its .mtl colour
        page.screenshot(path=str(ARTIFACTS / 'twin-urdf-before.png'))

        joints.publish(roslibpy.Message(joint_state(math.pi / 2)))
        page.wait_for_function("Math.abs(twin.model.robot.joints.wheel_joint.angle - Math.PI / 2) < 1e-6", timeout=WAIT)
        frames = page.evaluate('twin.state.frames')
        page.wait_for_function(f'twin.state.frames > {frames + 3}', timeout=WAIT)
        after = page.evaluate(MASKS)
        page.screenshot(path=str(ARTIFACTS / 'twin-urdf-after.png'))
        a, b = set(before['green']), set(after['green'])
        assert len(b) > 100
        assert len(a ^ b) > 0.5 * min(len(a), len(b)), (len(a), len(b), len(a ^ b))   # the wheel's pixels moved
        o1, o2 = set(before['orange']), set(after['orange'])
        assert len(o1 & o2) > 0.8 * len(o1)                                              # the body stayed
        assert not errors, errors


def test_the_map_draws_in_the_teleop_pages_world_view(chromium, bot):
    gw, _ = bot
    with tablet_page(chromium, gw.http_url + 'teleop?ns=/bot') as (page, errors):
        page.wait_for_function("document.body?.dataset.ready === 'true' && !!window.teleop", timeout=WAIT)
        page.wait_for_function('window.teleop.world?.grid?.w > 0', timeout=WAIT)
        assert page.is_visible('#world')
        grid = page.evaluate('({ w: teleop.world.grid.w, h: teleop.world.grid.h, frame: teleop.world.grid.frame })')
        assert grid == {'w': 6.0, 'h': 6.0, 'frame': 'map'}, grid
        page.wait_for_function('teleop.world.fit && teleop.world.fit.extent.x1 - teleop.world.fit.extent.x0 === 6', timeout=WAIT)
        counts = page.evaluate("""() => {
          const c = document.querySelector('#world');
          const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
          let free = 0, wall = 0;
          for (let i = 0; i < px.length; i += 4) {
            if (px[i] > 190 && px[i + 1] > 190 && px[i + 2] > 200) free++;
            else if (px[i] < 40 && px[i + 1] < 40 && px[i + 2] < 40 && px[i + 3] === 255) wall++;
          }
          return { free, wall, all: px.length / 4 };
        }""")
        assert counts['free'] > 0.3 * counts['all'] and counts['wall'] > 100, counts   # the floor and its wall ring
        page.screenshot(path=str(ARTIFACTS / 'teleop-world-map.png'))
        assert not errors, errors


def test_a_tap_on_the_floor_sends_a_navigation_goal(chromium, bot):
    gw, _ = bot
    with tablet_page(chromium, gw.http_url + 'twin?ns=/bot') as (page, errors):
        page.wait_for_function("document.body.dataset.ready === 'true' && !!window.twin && twin.state.map", timeout=WAIT)
        assert page.is_visible('#goal')
        page.click('#goal')   # (first: the page's bar may change size with the button's state)
        # a floor point in front of the robot (x = 1.5, y = 0.5), where the page draws it
        target = page.evaluate("""() => {
          const v = new twin.robot.position.constructor(1.5, 0.5, 0).project(twin.camera);
          const r = twin.renderer.domElement.getBoundingClientRect();
          return { x: r.left + (v.x + 1) / 2 * r.width, y: r.top + (1 - v.y) / 2 * r.height };
        }""")
        page.mouse.click(target['x'], target['y'])
        goal = gw.nav.expect(lambda m: m.get('op') == 'send_action_goal', 20)
        assert goal['action'] == '/bot/navigate_to_pose' and goal['action_type'] == 'nav2_msgs/action/NavigateToPose'
        pose = goal['args']['pose']
        assert pose['header']['frame_id'] == 'map'
        assert abs(pose['pose']['position']['x'] - 1.5) < 0.05 and abs(pose['pose']['position']['y'] - 0.5) < 0.05, pose
        q = pose['pose']['orientation']
        assert abs(2 * math.atan2(q['z'], q['w']) - math.atan2(0.5, 1.0)) < 0.05   # facing away from the robot at (0.5, 0)
        page.wait_for_function("twin.state.goal?.startsWith('goal sent')", timeout=WAIT)
        gw.nav.send({'op': 'action_result', 'action': '/bot/navigate_to_pose', 'id': goal['id'], 'status': 4,
                     'values': {'error_code': 0, 'error_msg': ''}, 'result': True})
        page.wait_for_function("twin.state.goal === 'goal reached'", timeout=WAIT)
        assert not errors, errors


def test_the_urdf_flag_gives_the_model_of_a_robot_without_a_description_topic(chromium, start_gateway, tmp_path):
    """rosgate --urdf FILE: the page draws that description (its meshes from --mesh-path) for a
    robot that publishes only its joint states."""
    meshes = write_package(tmp_path)
    gw = start_gateway('--robot', 'none', '--mesh-path', str(meshes),
                       '--urdf', str(meshes / 'testbot' / 'urdf' / 'testbot.urdf'))
    with client(gw) as ros, tablet_page(chromium) as (page, errors):
        joints = roslibpy.Topic(ros, '/bot2/joint_states', 'sensor_msgs/msg/JointState')
        joints.advertise()
        open_page(page, gw.http_url + 'twin?ns=/bot2')
        page.wait_for_function("twin.state.model === 'urdf' && twin.state.meshes === 'missing'", timeout=WAIT)
        assert page.evaluate('twin.state.urdfFrom') == '--urdf'
        assert page.evaluate('twin.state.missing') == ['package://testbot/meshes/missing.stl']
        joints.publish(roslibpy.Message(joint_state(1.25)))
        page.wait_for_function('Math.abs(twin.model.robot.joints.wheel_joint.angle - 1.25) < 1e-6', timeout=WAIT)
        assert not errors, errors
