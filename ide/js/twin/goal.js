// A navigation goal from the twin: where the robot has a nav2 NavigateToPose action server
// (``navigate_to_pose`` in its namespace), a "goal" button appears; the next tap on the floor sends
// the robot there (send_action_goal, through the gateway's rules like any command), facing away
// from where it stands. The goal shows as an arrow until its result comes back.
import * as THREE from 'three';
import { t, num } from '../i18n.js';

export const NAVIGATE = 'nav2_msgs/action/NavigateToPose';
let calls = 0;

function actionServers(ros) {
  const id = `call_service:/rosapi/action_servers:goal.${++calls}`;
  return new Promise((resolve) => {
    ros.once(id, (m) => resolve(m.result === false ? [] : m.values?.action_servers ?? []));
    ros.callOnConnection({ op: 'call_service', id, service: '/rosapi/action_servers', args: {} });
  });
}

// The point of the floor (z = 0) under a pointer event, or null.
function floorPoint(twin, event) {
  const rect = twin.renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1,
    -((event.clientY - rect.top) / rect.height) * 2 + 1);
  const ray = new THREE.Raycaster();
  ray.setFromCamera(ndc, twin.camera);
  return ray.ray.intersectPlane(new THREE.Plane(new THREE.Vector3(0, 0, 1), 0), new THREE.Vector3());
}

/**
 * Offers goals when `${ns}/navigate_to_pose` exists. rosNow() gives the page's connection at the
 * moment (its link makes a new one after an outage; null while there is none); frame() names the
 * frame of the floor (the map's); onState(text) tells the page. Returns {action, send(x, y, yaw)}
 * or null.
 */
export async function offerGoals(rosNow, twin, { ns, frame, onState }) {
  const action = `${ns}/navigate_to_pose`;
  if (!(await actionServers(rosNow())).includes(action)) return null;
  const button = document.createElement('button');
  button.type = 'button';
  button.id = 'goal';
  button.textContent = t('goal.button');
  button.title = t('goal.title');
  document.querySelector('#bar').append(button);
  const arrow = new THREE.ArrowHelper(new THREE.Vector3(1, 0, 0), new THREE.Vector3(), 0.5, 0x00e5ff, 0.15, 0.1);
  arrow.visible = false;
  twin.scene.add(arrow);
  let armed = false;
  let seq = 0;
  const send = (x, y, yaw) => {
    const ros = rosNow();
    if (!ros) { onState(t('goal.failed', { why: t('status.lost') })); return null; }
    const id = `send_action_goal:${action}:twin.${++seq}`;
    arrow.position.set(x, y, 0.05);
    arrow.setDirection(new THREE.Vector3(Math.cos(yaw), Math.sin(yaw), 0));
    arrow.visible = true;
    onState(t('goal.sent', { x: num(x, 2), y: num(y, 2) }));
    ros.once(id, (m) => {
      if (m.op === 'status') return;
      arrow.visible = false;
      onState(m.result === false ? t('goal.failed', { why: m.status ?? m.values?.error_msg ?? t('goal.refused') }) : t('goal.reached'));
    });
    ros.callOnConnection({
      op: 'send_action_goal', id, action, action_type: NAVIGATE,
      args: { pose: { header: { frame_id: frame() }, pose: {
        position: { x, y, z: 0 }, orientation: { x: 0, y: 0, z: Math.sin(yaw / 2), w: Math.cos(yaw / 2) } } },
      behavior_tree: '' },
    });
    return id;
  };
  button.onclick = () => { armed = !armed; button.setAttribute('aria-pressed', String(armed)); };
  let down = null;
  const canvas = twin.renderer.domElement;
  canvas.addEventListener('pointerdown', (e) => { down = { x: e.clientX, y: e.clientY }; });
  canvas.addEventListener('pointerup', (e) => {
    if (!armed || !down || Math.hypot(e.clientX - down.x, e.clientY - down.y) > 6) return;   // a drag orbits
    const p = floorPoint(twin, e);
    if (!p) return;
    armed = false;
    button.setAttribute('aria-pressed', 'false');
    const from = twin.robot?.position ?? new THREE.Vector3();
    send(p.x, p.y, Math.atan2(p.y - from.y, p.x - from.x));
  });
  return { action, send };
}
