// /twin: the robot in 3D (three.js), as it is now. The model: the robot's own URDF when it
// publishes /robot_description (urdf-loader; meshes it cannot fetch stay out, its primitives
// show), else a built-in one for the sim's rover and turtle. Posed from TF and odometry (the
// rover: tf_static world -> odom, then odom), the turtle from its pose; the laser scan as points
// around it; the world's markers (walls, bounds); the body blinks red below 20 % battery and
// each wheel takes its motor's temperature colour (as the dashboard's gauges: 50 °C amber,
// 65 °C red). Orbit and zoom by mouse or touch (OrbitControls); the view follows the robot.
import { Ros, Topic, Service } from 'roslib';
import * as THREE from 'three';
import { OrbitControls, URDFLoader } from 'three';
import { t, num } from './i18n.js';

const params = new URLSearchParams(location.search);
const ns = (params.get('ns') || '').replace(/\/+$/, '');
const name = (n) => `${ns}${n}`;
const $ = (s) => document.querySelector(s);
const LOW_BATTERY = 0.2;
const TEMP = { warn: 50, danger: 65 };
const COLOURS = { body: 0xf08c1a, turtle: 0x3fa34d, wheel: 0x444a55, warn: 0xffb300, danger: 0xe53935, scan: 0xff3b3b };
const ARROW = 0, CUBE = 1, LINE_STRIP = 4, LINE_LIST = 5, DELETE = 2, DELETEALL = 3;

const state = { model: null, pose: null, battery: null, temps: {}, frames: 0, markers: 0, scanPoints: 0, blinkOn: false };
const twin = { state, onBattery, onTemperature };   // the handlers: for tests
window.twin = twin;

// ---- the scene ---------------------------------------------------------------
function makeScene() {
  const view = $('#view');
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  } catch (e) {
    view.textContent = t('twin.no.webgl', { error: e.message });
    state.error = String(e.message);
    return null;
  }
  renderer.setPixelRatio(Math.min(devicePixelRatio, 2));
  view.append(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x151925);
  const camera = new THREE.PerspectiveCamera(50, 1, 0.05, 200);
  camera.up.set(0, 0, 1);                       // ROS: z is up
  camera.position.set(-2.2, -2.2, 2.0);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.enableDamping = true;
  controls.target.set(0, 0, 0);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x30364a, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.4);
  sun.position.set(3, -4, 8);
  scene.add(sun);
  const grid = new THREE.GridHelper(40, 80, 0x3b4460, 0x262c40);
  grid.rotation.x = Math.PI / 2;
  scene.add(grid);
  const resize = () => {
    const w = view.clientWidth || 300, h = view.clientHeight || 240;
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  };
  new ResizeObserver(resize).observe(view);
  resize();
  Object.assign(twin, { renderer, scene, camera, controls });
  return twin;
}

// ---- built-in models ------------------------------------------------------------
function material(colour) { return new THREE.MeshStandardMaterial({ color: colour, roughness: 0.6 }); }

function rover() {
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

function turtle() {
  const g = new THREE.Group();
  const shell = new THREE.Mesh(new THREE.SphereGeometry(0.5, 24, 12), material(COLOURS.turtle));
  shell.scale.set(1, 0.8, 0.35);
  shell.position.z = 0.1;
  const head = new THREE.Mesh(new THREE.SphereGeometry(0.15, 16, 10), material(0x9ccc65));
  head.position.set(0.55, 0, 0.1);
  g.add(shell, head);
  return { group: g, body: shell.material, wheels: {}, scanHeight: 0.2 };
}

function fromUrdf(xml) {
  const loader = new URDFLoader();
  loader.loadMeshCb = (path, manager, done) => done(null);   // meshes are not served here
  const robot = loader.parse(xml);
  const g = new THREE.Group();
  g.add(robot);
  let body = null;
  robot.traverse((o) => { if (o.isMesh && !body) { o.material = material(COLOURS.body); body = o.material; } });
  return { group: g, body: body ?? material(COLOURS.body), wheels: {}, scanHeight: 0.2 };
}

function useModel(kind, model) {
  if (twin.robot) twin.scene.remove(twin.robot);
  twin.model = model;
  twin.robot = model.group;
  twin.scene.add(model.group);
  state.model = kind;
  $('#model').textContent = t('twin.model', { kind });
  model.group.add(twin.scan);
  twin.scan.position.z = model.scanHeight;
}

// ---- what the robot says -----------------------------------------------------
const yawOf = (q) => Math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z));

function setPose(x, y, yaw) {
  const robot = twin.robot;
  if (!robot) return;
  const before = robot.position.clone();
  robot.position.set(x, y, 0);
  robot.rotation.set(0, 0, yaw);
  const moved = robot.position.clone().sub(before);
  if (state.pose === null) {                   // the first pose: look at the robot
    twin.controls.target.set(x, y, 0);
    twin.camera.position.set(x - 2.2, y - 2.2, 2.0);
  } else {                                     // then follow it, keeping the user's angle and zoom
    twin.controls.target.add(moved);
    twin.camera.position.add(moved);
  }
  state.pose = { x, y, yaw };
}

let worldOdom = { x: 0, y: 0, yaw: 0 };
function onTfStatic(msg) {
  for (const t of msg.transforms) {
    if (t.header.frame_id === 'world' && /(^|\/)odom$/.test(t.child_frame_id)) {
      const tr = t.transform.translation;
      worldOdom = { x: tr.x, y: tr.y, yaw: yawOf(t.transform.rotation) };
    }
  }
}

function onOdom(msg) {
  const p = msg.pose.pose.position, yaw = yawOf(msg.pose.pose.orientation);
  const c = Math.cos(worldOdom.yaw), s = Math.sin(worldOdom.yaw);
  setPose(worldOdom.x + c * p.x - s * p.y, worldOdom.y + s * p.x + c * p.y, worldOdom.yaw + yaw);
}

function onScan(msg) {
  const pts = [];
  msg.ranges.forEach((r, i) => {
    if (r === null || !Number.isFinite(r) || r < msg.range_min || r > msg.range_max) return;
    const a = msg.angle_min + i * msg.angle_increment;
    pts.push(r * Math.cos(a), r * Math.sin(a), 0);
  });
  twin.scan.geometry.setAttribute('position', new THREE.Float32BufferAttribute(pts, 3));
  twin.scan.geometry.computeBoundingSphere();
  state.scanPoints = pts.length / 3;
}

function onBattery(msg) {
  const pct = msg.percentage;
  state.battery = pct;
  const el = $('#battery');
  el.textContent = Number.isFinite(pct) ? t('twin.battery', { pct: num(pct * 100, 0) }) : t('twin.battery.unknown');
  el.dataset.level = pct <= LOW_BATTERY ? 'danger' : pct <= 0.5 ? 'warn' : 'ok';
}

function tempColour(t) { return t >= TEMP.danger ? COLOURS.danger : t >= TEMP.warn ? COLOURS.warn : COLOURS.wheel; }

function onTemperature(side, msg) {
  state.temps[side] = msg.temperature;
  twin.model?.wheels[side]?.material.color.setHex(tempColour(msg.temperature));
  $('#motors').textContent = t('twin.motors', { temps: ['left', 'right'].map((s) => num(state.temps[s] ?? NaN, 1)).join(' / ') });
}

// world/markers: the walls and the bounds (the robots and the scan are drawn from their own topics)
const markers = new Map();
function onMarkers(msg) {
  for (const m of msg.markers) {
    if (m.action === DELETEALL) {
      for (const [k, o] of markers) if (k.startsWith(`${m.ns}/`) || !m.ns) { twin.scene.remove(o); markers.delete(k); }
      continue;
    }
    const key = `${m.ns}/${m.id}`;
    const old = markers.get(key);
    if (old) { twin.scene.remove(old); markers.delete(key); }
    if (m.action === DELETE || m.ns === 'robots' || m.ns === 'scan' || m.type === ARROW) continue;
    const obj = markerObject(m);
    if (!obj) continue;
    markers.set(key, obj);
    twin.scene.add(obj);
  }
  state.markers = markers.size;
}

function markerObject(m) {
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

// ---- the loop --------------------------------------------------------------------
function animate(now) {
  requestAnimationFrame(animate);
  const m = twin.model;
  if (m) {
    const low = Number.isFinite(state.battery) && state.battery <= LOW_BATTERY;
    state.blinkOn = low && Math.floor(now / 400) % 2 === 0;
    m.body.emissive?.setHex(state.blinkOn ? 0xff0000 : 0x000000);
    state.lowBattery = low;
  }
  twin.controls.update();
  twin.renderer.render(twin.scene, twin.camera);
  state.frames += 1;
}

// ---- the connection ------------------------------------------------------------
function setStatus(s, text) { const el = $('#status'); el.dataset.state = s; el.textContent = text; document.body.dataset.connection = s; }

function listen(ros, topic, type, fn, throttle = 0) {
  new Topic({ ros, name: topic, messageType: type, throttle_rate: throttle, queue_length: 1 }).subscribe(fn);
}

async function topics(ros) {
  const srv = new Service({ ros, name: '/rosapi/topics', serviceType: 'rosapi/Topics' });
  return new Promise((resolve) => srv.callService({}, (r) => resolve(new Set(r.topics)), () => resolve(new Set())));
}

async function start(ros) {
  const have = await topics(ros);
  if (have.has(name('/robot_description'))) {
    listen(ros, name('/robot_description'), 'std_msgs/msg/String', (msg) => {
      try { useModel('urdf', fromUrdf(msg.data)); } catch (e) { state.error = `robot_description: ${e.message}`; }
    });
  }
  if (have.has(name('/odom')) || have.has(name('/battery_state'))) {
    if (!twin.model) useModel('rover', rover());
    listen(ros, name('/tf_static'), 'tf2_msgs/msg/TFMessage', onTfStatic);
    listen(ros, name('/odom'), 'nav_msgs/msg/Odometry', onOdom, 40);
    listen(ros, name('/scan'), 'sensor_msgs/msg/LaserScan', onScan, 200);
    listen(ros, name('/battery_state'), 'sensor_msgs/msg/BatteryState', onBattery, 500);
    for (const side of ['left', 'right']) {
      listen(ros, name(`/motor/${side}/temperature`), 'sensor_msgs/msg/Temperature', (m) => onTemperature(side, m), 500);
    }
  } else if (have.has(name('/turtle1/pose'))) {
    if (!twin.model) useModel('turtle', turtle());
    listen(ros, name('/turtle1/pose'), 'turtlesim/msg/Pose', (p) => setPose(p.x, p.y, p.theta), 40);
  } else {
    state.error = t('twin.no.robot', { ns: ns || '/' });
    $('#model').textContent = state.error;
  }
  listen(ros, name('/world/markers'), 'visualization_msgs/msg/MarkerArray', onMarkers);
  document.body.dataset.ready = 'true';
}

function connect() {
  const url = params.get('url') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`;
  const ros = new Ros({});
  ros.on('connection', () => { setStatus('connected', t('status.connected')); start(ros); });
  ros.on('close', () => setStatus('closed', t('status.disconnected')));
  ros.on('error', () => setStatus('error', t('status.error')));
  ros.connect(url);
}

if (params.has('embed')) document.body.dataset.embed = '';   // the teleop page's 3D panel
$('#ns').value = ns;
$('#ns').addEventListener('change', (e) => {
  const q = new URLSearchParams(location.search);
  q.set('ns', e.target.value.trim());
  location.search = q.toString();
});
$('#teleop-link').href = `teleop${ns ? `?ns=${encodeURIComponent(ns)}` : ''}`;
if (makeScene()) {
  twin.scan = new THREE.Points(new THREE.BufferGeometry(), new THREE.PointsMaterial({ color: COLOURS.scan, size: 0.04 }));
  requestAnimationFrame(animate);
  connect();
}
