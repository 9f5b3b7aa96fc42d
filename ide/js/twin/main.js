// /twin: the robot in 3D (three.js), as it is now. The model: the robot's own description first
// (GET api/description: the gateway's --urdf file, else its robot_description topic, else
// robot_state_publisher's parameter, xacro expanded by the gateway; urdf.js) with its meshes and
// its joints moved by its joint_states; else by what the robot really publishes (the graph's
// publishers, not its topic names: a page that once looked for /odom on a turtle left the name
// there), a built-in one for the sim's rover and turtle. Only published topics are subscribed. Placed by TF (frames.js: its base link in the root of the tree),
// else odometry (the rover: tf_static world -> odom, then odom), the turtle by its pose; its map
// and paths on the floor (map3d.js); the laser scan as points
// around it; the world's markers (walls, bounds); the body blinks red below 20 % battery and
// each wheel takes its motor's temperature colour (as the dashboard's gauges: 50 °C amber,
// 65 °C red). Orbit and zoom by mouse or touch (OrbitControls); the view follows the robot.
import { Topic, Service } from 'roslib';
import * as THREE from 'three';
import { OrbitControls } from 'three';
import { loadUrdf, applyJointState, description, isXacro } from './urdf.js';
import { publishedOf } from '../robot/graph.js';
import { COLOURS, rover, turtle, markerObject } from './models.js';
import { Frames } from './frames.js';
import { MapLayer } from './map3d.js';
import { mapSubscribe } from '../views/grid.js';
import { offerGoals } from './goal.js';
import { Drawables } from './drawables.js';
import { Link } from '../link/link.js';
import { t, tn, num } from '../i18n.js';

const params = new URLSearchParams(location.search);
const ns = (params.get('ns') || '').replace(/\/+$/, '');
const name = (n) => `${ns}${n}`;
const $ = (s) => document.querySelector(s);
const LOW_BATTERY = 0.2;
const TEMP = { warn: 50, danger: 65 };
const ARROW = 0, DELETE = 2, DELETEALL = 3;

const state = {
  model: null, pose: null, battery: null, temps: {}, frames: 0, markers: 0, scanPoints: 0, blinkOn: false,
  meshes: null, missing: [], joints: 0, tf: false, map: null, paths: 0, urdfFrom: null,
};
// the page's state, exported with its handlers (for tests: tests/support/page_state.js)
export const twin = { state, onBattery, onTemperature, frames: new Frames() };

// ---- the scene ---------------------------------------------------------------
function makeScene() {
  const view = $('#view');
  let renderer;
  try {
    // asked first, so that a browser without WebGL 2 (three's need) gets the page's words, not
    // three's console errors
    const canvas = document.createElement('canvas');
    const context = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true, alpha: false, stencil: false });
    if (!context) throw new Error(t('twin.no.webgl2'));
    renderer = new THREE.WebGLRenderer({ canvas, context, antialias: true, preserveDrawingBuffer: true });
  } catch (e) {
    view.textContent = t('twin.no.webgl', { error: e.message });
    view.dataset.webgl = 'none';   // (the mark, whatever the words' language: for tests)
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

// A notice over the view (missing meshes, no description): what a person should know.
function notice(text) {
  let el = $('#notice');
  if (!el) {
    el = document.createElement('p');
    el.id = 'notice';
    el.setAttribute('role', 'status');
    $('#view').after(el);
  }
  el.hidden = false;
  el.textContent = text;
}

function useUrdf(xml, from) {
  state.urdfText = xml;
  const problems = [];
  const model = loadUrdf(xml, { onProblem: (p) => problems.push(p) });
  state.meshes = 'loading';
  state.urdfFrom = from;
  useModel('urdf', model);
  model.loaded.then((missing) => {
    if (twin.model !== model) return;
    state.missing = missing;
    state.meshes = missing.length ? 'missing' : 'loaded';
    if (missing.length) {
      notice(tn('twin.meshes.missing', missing.length, { problems: problems.join('; ') }));
    }
    placeByTf();
  });
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
  follow(before, x, y, yaw);
}

// The URDF model's root link where TF puts it (under a namespace, its frames may be prefixed).
function placeByTf() {
  const robot = twin.robot, urdf = twin.model?.robot;
  if (!robot || twin.model?.kind !== 'urdf') return false;
  const prefix = ns ? `${ns.replace(/^\//, '')}/` : '';
  const frame = [`${prefix}${urdf.name}`, urdf.name].find((f) => twin.frames.has(f));
  if (!frame) return false;
  const before = robot.position.clone();
  twin.frames.place(robot, frame);
  state.tf = true;
  state.rootFrame = twin.frames.root(frame);   // the floor's frame (world, map or odom)
  follow(before, robot.position.x, robot.position.y, yawOf(robot.quaternion));
  return true;
}

function onTf(msg) {
  twin.frames.update(msg);
  placeByTf();
  twin.map?.place();
  twin.drawables?.onTf();
}

function follow(before, x, y, yaw) {
  const moved = twin.robot.position.clone().sub(before);
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
  if (state.tf) return;                        // TF places the robot
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

function listen(ros, topic, type, fn, throttle = 0, queue = 1) {
  new Topic({ ros, name: topic, messageType: type, throttle_rate: throttle, queue_length: queue }).subscribe(fn);
}

// topic -> type, of every topic on the graph
async function topics(ros) {
  const srv = new Service({ ros, name: '/rosapi/topics', serviceType: 'rosapi/Topics' });
  return new Promise((resolve) => srv.callService({},
    (r) => resolve(new Map(r.topics.map((t, i) => [t, r.types[i]]))), () => resolve(new Map())));
}

let calls = 0;
// A rosapi call's values (rejected on a refusal).
function rosapi(ros, service, args = {}) {
  const id = `call_service:${service}:twin.${++calls}`;
  return new Promise((resolve, reject) => {
    ros.once(id, (m) => (m.result === false ? reject(new Error(m.values)) : resolve(m.values)));
    ros.callOnConnection({ op: 'call_service', id, service, args });
  });
}

// The topics this page may draw from, of those on the graph: what the robot publishes.
const DRAWN_TYPES = new Set(['sensor_msgs/msg/JointState', 'tf2_msgs/msg/TFMessage', 'nav_msgs/msg/OccupancyGrid',
  'nav_msgs/msg/Path', 'nav_msgs/msg/Odometry', 'sensor_msgs/msg/LaserScan', 'sensor_msgs/msg/BatteryState',
  'sensor_msgs/msg/Temperature', 'turtlesim/msg/Pose', 'visualization_msgs/msg/MarkerArray', 'std_msgs/msg/String',
  'visualization_msgs/msg/Marker', 'sensor_msgs/msg/PointCloud2', 'geometry_msgs/msg/PoseStamped']);
function published(ros, types) {
  const norm = (type) => (String(type).split('/').length === 2 ? type.replace('/', '/msg/') : type);
  const wanted = [...types].filter(([t, type]) => DRAWN_TYPES.has(norm(type)) && (!ns || t.startsWith(`${ns}/`)
    || ['/tf', '/tf_static', '/map'].includes(t))).map(([t]) => t);
  return publishedOf((service, args) => rosapi(ros, service, args), wanted);
}

// The map made to measure (grid.js).
function listenMap(ros, topic) {
  ros.on(topic, (m) => {
    twin.map.onGrid(m.msg);
    state.map = { topic, ...twin.map.info };
  });
  ros.callOnConnection(mapSubscribe(topic, `subscribe:${topic}:twin`));
}

// The robot's description as the gateway finds it (api/description); then, where it came from the
// robot_description topic, a new one published there replaces it (xacro: expanded by the gateway).
async function describe(ros, has) {
  const found = await description(ns);
  const use = (xml, from) => {
    try { if (xml && xml !== state.urdfText) useUrdf(xml, from); } catch (e) { state.error = `robot_description: ${e.message}`; notice(state.error); }
  };
  if (found.error) notice(t('twin.description.error', { error: found.error }));
  if (found.urdf) use(found.urdf, found.from);
  if (found.from !== '--urdf' && has(name('/robot_description'))) {
    let last = null;
    listen(ros, name('/robot_description'), 'std_msgs/msg/String', async (msg) => {
      if (msg.data === last) return;
      last = msg.data;
      if (!isXacro(msg.data)) { use(msg.data, 'topic'); return; }
      const again = await description(ns);
      if (again.urdf) use(again.urdf, again.from);
    });
  }
  return Boolean(found.urdf);
}

async function start(ros) {
  const types = await topics(ros);
  const present = await published(ros, types);
  const has = (t) => present.has(t);
  state.published = [...present].sort();
  const described = await describe(ros, has);
  if (has(name('/joint_states'))) {
    listen(ros, name('/joint_states'), 'sensor_msgs/msg/JointState', (msg) => {
      if (twin.model?.kind === 'urdf') state.joints += applyJointState(twin.model.robot, msg);
    }, 0, 10);
  }
  for (const t of new Set([name('/tf'), name('/tf_static'), '/tf', '/tf_static'])) {
    if (has(t)) listen(ros, t, 'tf2_msgs/msg/TFMessage', onTf, 0, 50);
  }
  const map = [name('/map'), '/map'].find((t) => types.get(t) === 'nav_msgs/msg/OccupancyGrid');
  if (map) listenMap(ros, map);
  for (const [t, type] of types) {
    if (type === 'nav_msgs/msg/Path' && (t.startsWith(`${ns}/`) || !ns)) {
      listen(ros, t, type, (msg) => { twin.map.onPath(t, msg); state.paths = twin.map.paths.size; }, 200);
    }
  }
  if (has(name('/odom')) || has(name('/battery_state'))) {
    if (!twin.model && !described) useModel('rover', rover());
    const listenIf = (topic, ...rest) => { if (has(topic)) listen(ros, topic, ...rest); };
    listenIf(name('/tf_static'), 'tf2_msgs/msg/TFMessage', onTfStatic);
    listenIf(name('/odom'), 'nav_msgs/msg/Odometry', onOdom, 40);
    listenIf(name('/scan'), 'sensor_msgs/msg/LaserScan', onScan, 200);
    listenIf(name('/battery_state'), 'sensor_msgs/msg/BatteryState', onBattery, 500);
    for (const side of ['left', 'right']) {
      listenIf(name(`/motor/${side}/temperature`), 'sensor_msgs/msg/Temperature', (m) => onTemperature(side, m), 500);
    }
  } else if (has(name('/turtle1/pose'))) {
    if (!twin.model && !described) useModel('turtle', turtle());
    listen(ros, name('/turtle1/pose'), 'turtlesim/msg/Pose', (p) => setPose(p.x, p.y, p.theta), 40);
  } else if (!described) {
    state.error = t('twin.no.robot', { ns: ns || '/' });
    $('#model').textContent = state.error;
  }
  if (has(name('/world/markers'))) listen(ros, name('/world/markers'), 'visualization_msgs/msg/MarkerArray', onMarkers);
  twin.drawables ??= new Drawables(twin, ns);   // point clouds, markers, goals (drawables.js): kept across links
  twin.drawables.attach(ros, new Map([...types].filter(([t]) => has(t))));
  twin.goals ??= await offerGoals(() => twin.link.ros, twin, {   // (offered once; asked again while it is not)
    ns, frame: () => twin.map.frame || state.rootFrame || 'map', onState: (text) => { state.goal = text; notice(text); },
  });
  document.body.dataset.ready = 'true';
}

// One Link (link.js), as the other pages: seen by its pings, made again after an outage or a
// gateway's restart. Each new connection subscribes again (start); the scene, the model and what
// was drawn are kept, and the robot moves on from where it was drawn.
function connect() {
  const url = params.get('url') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`;
  const link = new Link(url);
  twin.link = link;
  link.addEventListener('state', (e) => {
    const s = e.detail;
    setStatus(s, t(s === 'connected' ? 'status.connected' : s === 'lost' ? 'status.lost' : 'status.connecting'));
  });
  link.addEventListener('open', (e) => { start(e.detail); });
  setStatus('connecting', t('status.connecting'));
  link.start();
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
  twin.map = new MapLayer(twin.scene, twin.frames);
  twin.scan = new THREE.Points(new THREE.BufferGeometry(), new THREE.PointsMaterial({ color: COLOURS.scan, size: 0.04 }));
  requestAnimationFrame(animate);
  connect();
} else {
  document.body.dataset.ready = 'true';   // it said why it cannot draw: nothing more starts
}
