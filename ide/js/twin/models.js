// The built-in models of the sim's robots (the rover, the turtle) for a robot without a
// description, and the world's markers (walls, bounds) as three.js objects.
import * as THREE from 'three';
import { markerMesh } from './markers3d.js';

export const COLOURS = { body: 0xf08c1a, turtle: 0x3fa34d, wheel: 0x444a55, warn: 0xffb300, danger: 0xe53935, scan: 0xff3b3b };
const CUBE = 1, LINE_STRIP = 4, LINE_LIST = 5;

function material(colour) { return new THREE.MeshStandardMaterial({ color: colour, roughness: 0.6 }); }

export function rover() {
  const g = new THREE.Group();
  const body = new THREE.Mesh(new THREE.BoxGeometry(0.4, 0.26, 0.12), material(COLOURS.body));
  body.position.z = 0.1;
  const nose = new THREE.Mesh(new THREE.BoxGeometry(0.06, 0.2, 0.06), material(0xffffff));
  nose.position.set(0.2, 0, 0.12);
  const lidar = new THREE.Mesh(new THREE.CylinderGeometry(0.05, 0.05, 0.05, 20), material(0x222222));
  lidar.rotation.x = Math.PI / 2;
  lidar.position.z = 0.19;
  const wheels = {};
  for (const [side, y] of [['left', 0.165], ['right', -0.165]]) {
    const w = new THREE.Mesh(new THREE.CylinderGeometry(0.07, 0.07, 0.05, 24), material(COLOURS.wheel));
    w.position.set(0, y, 0.07);     // a cylinder's axis is y: the wheel's axle already
    wheels[side] = w;
    g.add(w);
  }
  g.add(body, nose, lidar);
  return { group: g, body: body.material, wheels, scanHeight: 0.17 };
}

export function turtle() {
  const g = new THREE.Group();
  const shell = new THREE.Mesh(new THREE.SphereGeometry(0.5, 24, 12), material(COLOURS.turtle));
  shell.scale.set(1, 0.8, 0.35);
  shell.position.z = 0.1;
  const head = new THREE.Mesh(new THREE.SphereGeometry(0.15, 16, 10), material(0x9ccc65));
  head.position.set(0.55, 0, 0.1);
  g.add(shell, head);
  return { group: g, body: shell.material, wheels: {}, scanHeight: 0.2 };
}

export function markerObject(m) {
  if (![CUBE, LINE_STRIP, LINE_LIST].includes(m.type)) return markerMesh(m);   // every other type: markers3d.js
  const colour = new THREE.Color(m.color.r, m.color.g, m.color.b);
  let obj = null;
  if (m.type === CUBE) {
    obj = new THREE.Mesh(new THREE.BoxGeometry(m.scale.x, m.scale.y, m.scale.z),
      new THREE.MeshStandardMaterial({ color: colour, transparent: m.color.a < 1, opacity: m.color.a }));
  } else if (m.type === LINE_STRIP || m.type === LINE_LIST) {
    const g = new THREE.BufferGeometry().setFromPoints(m.points.map((p) => new THREE.Vector3(p.x, p.y, p.z + 0.01)));
    const mat = new THREE.LineBasicMaterial({ color: colour.getHex() === 0x333333 ? 0x8890a8 : colour });
    obj = m.type === LINE_STRIP ? new THREE.Line(g, mat) : new THREE.LineSegments(g, mat);
  } else {
    return null;
  }
  const p = m.pose.position, q = m.pose.orientation;
  obj.position.set(p.x, p.y, p.z);
  obj.quaternion.set(q.x, q.y, q.z, q.w);
  return obj;
}
