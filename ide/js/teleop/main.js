// The teleop page: joystick, keys and buttons publish a velocity at a fixed rate while
// held and zero on release, within the robot's own limits (its node parameters); a world view,
// gauges, camera and history plots show what the robot reports (the world, camera and gauges
// only where their topics exist: a turtlesim lesson on a phone had a black camera and empty
// gauges, and no turtle). On a fleet the page drives only a station of its own (claimed, or
// picked and free), and nothing after the teacher's Release until a new claim.
import nipplejs from 'nipplejs';
import { field, zeroVelocity, withNamespace } from '../../runtime/util.js';
import { showCameras } from './cameras.js';
import { DriverLease, bindDriverBadge, DRIVER_TOPIC } from '../robot/driver.js';
import { bindNamespace, CLAIM_SERVICE, STOPPED } from '../robot/robotns.js';
import { gauge, History, SAMPLE_EVERY } from './dashboard.js';
import { Gauges, batteryPercent, batteryLevel, fileLimits } from './gauges.js';
import { publishedOf } from '../robot/graph.js';
import { WorldView } from '../views/worldview.js';
import { bindSpan } from './history.js';
import { HomeEstimate } from './gohome.js';
import { Link } from '../link/link.js';
import { mountRecorder } from '../lab/recorder.js';
import { mountBooking } from '../lab/booking.js';
import { watchGamepads } from './gamepad.js';
import { t, num } from '../i18n.js';

const $ = (s) => document.querySelector(s);
const params = new URLSearchParams(location.search);
const state = {
  ros: null,
  joy: { x: 0, y: 0, active: false },
  pad: { x: 0, y: 0, active: false },        // a gamepad's left stick while its dead-man button is held
  keys: new Set(),
  timer: null,
  published: 0,
  advertised: '',
  battery: null,
  frames: 0,
  subs: [],
  present: new Set(),                        // the topics the robot publishes, of those the page shows
  limits: { linear: null, angular: null },   // from the robot's node parameters, when it has them
  blocked: '',                               // why this page may not drive now ('' : it may)
};
export { state as teleop };   // the page's state (for tests: tests/support/page_state.js)
const lease = new DriverLease();
const home = new HomeEstimate(document.querySelector('#home'));   // enough charge to drive back?
state.home = home;
state.lease = lease;

// ---- connection -----------------------------------------------------------
function setStatus(s, text) { const el = $('#status'); el.dataset.state = s; el.textContent = text; document.body.dataset.connection = s; }

// One link, made again by itself (link.js); its loss stops driving at once: what the page would
// send cannot arrive, and the gateway stops the robot when commands stop coming.
function connect() {
  const url = params.get('url') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`
    + (params.get('name') ? `?name=${encodeURIComponent(params.get('name'))}` : '');
  const link = new Link(url);
  state.link = link;
  setStatus('connecting', t('status.connecting'));
  link.addEventListener('open', (e) => {
    const ros = e.detail;
    state.ros = ros;
    state.advertised = '';
    setStatus('connected', t('status.connected'));
    lease.attach(ros);
    state.robotNs.attach(ros);
    onConnected();
  });
  link.addEventListener('lost', () => {
    state.keys.clear();
    state.joy = { x: 0, y: 0, active: false };
    state.gamepad?.stop();
    if (state.timer) { clearInterval(state.timer); state.timer = null; }
    state.ros = null;
    setStatus('lost', t('status.lost.stopped'));
  });
  setInterval(() => { $('#link').textContent = link.describe(); }, 250);
  link.start();
}

let subSeq = 0;
function subscribe(topic, type, onMsg, extra = {}) {
  const ros = state.ros;
  const id = `subscribe:${topic}:teleop.${++subSeq}`;
  const listener = (m) => onMsg(m.msg);
  ros.on(topic, listener);
  ros.callOnConnection({ op: 'subscribe', id, topic, type, ...extra });
  const sub = { topic, close: () => { ros.off(topic, listener); ros.callOnConnection({ op: 'unsubscribe', id, topic }); } };
  state.subs.push(sub);
  return sub;
}

function callRosapi(service, args = {}) {
  const ros = state.ros;
  const id = `call_service:${service}:teleop.${++subSeq}`;
  return new Promise((resolve, reject) => {
    ros.once(id, (m) => (m.result === false ? reject(new Error(m.values)) : resolve(m.values)));
    ros.callOnConnection({ op: 'call_service', id, service, args });
  });
}

async function onConnected() {
  try {
    const { services } = await callRosapi('/rosapi/services');
    const fleet = services.includes(CLAIM_SERVICE);
    const claiming = state.robotNs.claimable(fleet);   // on a fleet with no robot chosen this claims one
    if (fleet && !state.robotNs.get()) block(t('teleop.claiming'));
    const { topics, types } = await callRosapi('/rosapi/topics');
    if (topics.includes(DRIVER_TOPIC)) lease.watch();
    await claiming;                          // its answer, not this notice, has the last word
    const ns = state.robotNs.get();
    await dash.board.ready;
    applyGraph(topics, types, ns, await robotTopics(topics, types, ns));
    if (fleet && !ns) {
      block(state.robotNs.whyNot());
      resubscribe();
      return;
    }
    const vel = topics.filter((t, i) => /geometry_msgs\/(msg\/)?Twist(Stamped)?$/.test(types[i])
      && (!ns || t.startsWith(`${ns}/`)));
    $('#topics').replaceChildren(...topics.map((t) => new Option(t, t)));
    const topicEl = $('#topic');
    if (!params.get('topic') && !vel.includes(topicEl.value) && vel.length) {
      const preferred = withNamespace(ns, '/cmd_vel');
      topicEl.value = vel.includes(preferred) ? preferred : vel[0];
    }
    const type = types[topics.indexOf(topicEl.value)];
    if (type) $('#msgtype').value = /Stamped$/.test(type) ? 'geometry_msgs/msg/TwistStamped' : 'geometry_msgs/msg/Twist';
    block('');
    await applyLimits();
  } catch { /* rosapi unavailable: keep the defaults */ }
  resubscribe();
}

// ---- what the robot has: a world view where it publishes markers (turtlesim, the rover, a real
// robot with /world/markers), the camera, gauges and plots only where something publishes their
// topics. Nothing else is subscribed: a subscription to a topic the robot does not have would put
// it on the graph (ROS 2 lists a topic with subscribers only), where the history, the twin and the
// next page would take it for the robot's (a turtle "with" a battery and motors). -------------------
const SHOWN_TYPES = /^(sensor_msgs\/(msg\/)?(BatteryState|Temperature|JointState|Image|CompressedImage)|nav_msgs\/(msg\/)?(Odometry|OccupancyGrid)|visualization_msgs\/(msg\/)?MarkerArray)$/;

// The topics of the robot's graph this page could show, that something publishes.
function robotTopics(topics, types, ns) {
  const listed = new Set(topics);
  const fields = [...Object.values(fixedTopics(ns)), $('#camera-topic').value.trim(), withNamespace(ns, '/odom')];
  const shown = topics.filter((t, i) => SHOWN_TYPES.test(types[i] ?? '') && (!ns || t.startsWith(`${ns}/`)));
  return publishedOf(callRosapi, [...shown, ...fields.filter((t) => listed.has(t))]);
}

// The page as the graph says: present, the set of robotTopics.
function applyGraph(topics, types, ns, present) {
  state.present = present;
  state.graph = { topics, types };
  showWhatTheRobotHas(ns);
  fixedGauges(ns);
  const mine = topics.map((t, i) => [t, types[i]]).filter(([t]) => present.has(t));
  const found = dash.board.show(mine.map(([t]) => t), mine.map(([, type]) => type), ns);   // every gauge it has
  let added = 0;
  for (const spec of [...fixedSeries(ns), ...dash.board.plots()]) {                       // and its history
    if (!dash.series[spec.id] && present.has(spec.id === 'battery' ? $('#battery-topic').value.trim() : spec.topic)) {
      addSeries(spec, false);   // resubscribe() subscribes it, after this
      added += 1;
    }
  }
  if (added) dash.loadSpan?.();   // the span shown, with the gateway's history of the plots just added
  if (found) $('#battery-card').hidden = false;
  showCameras({ ros: state.ros, topics: mine.map(([t]) => t), types: mine.map(([, type]) => type), ns,
    main: $('#camera-topic').value.trim(), after: $('#camera-card') });
}

// The graph read again: a robot that started (or a topic that appeared) after the page is shown.
async function lookAgain(force = false) {
  if (!state.ros?.isConnected || document.hidden) return;
  try {
    const { topics, types } = await callRosapi('/rosapi/topics');
    const ns = state.robotNs.get();
    const present = await robotTopics(topics, types, ns);
    const same = present.size === state.present.size && [...present].every((t) => state.present.has(t));
    if (same && !force) return;
    applyGraph(topics, types, ns, present);
    resubscribe();
  } catch { /* rosapi unavailable: as it was */ }
}

function showWhatTheRobotHas(ns) {
  const has = (t) => state.present.has(t);
  const world = withNamespace(ns, '/world/markers');
  const drawn = has(world) || has(withNamespace(ns, '/map'));   // its markers, or only its map
  const camera = has($('#camera-topic').value.trim());
  $('#world-card').hidden = !drawn;
  document.body.toggleAttribute('data-world', drawn && !camera);   // the world in the camera's place
  if (drawn) {
    if (!state.world) state.world = new WorldView($('#world'), world);
    state.world.setTopic(world);
    if (state.world.ros !== state.ros) state.world.attach(state.ros);
    state.world.look(callRosapi);
  }
  $('#camera-card').hidden = !camera;
  for (const [el, topic] of Object.entries(fixedTopics(ns))) $(el).hidden = !has(topic);
  $('#battery-card').hidden = !Object.values(fixedTopics(ns)).some(has);
}

// The page's own gauges (the battery topic field, the rover's motors), by element
function fixedTopics(ns) {
  return { '#g-battery': $('#battery-topic').value.trim(), '#g-left': withNamespace(ns, '/motor/left/temperature'),
    '#g-right': withNamespace(ns, '/motor/right/temperature') };
}

// ---- the robot's limits: the node that takes the velocity topic says them ------------------
const LIMIT_PARAMS = {
  linear: ['max_linear_velocity', 'max_vel_x', 'max_linear_speed'],
  angular: ['max_angular_velocity', 'max_vel_theta', 'max_angular_speed'],
};

async function robotLimits(topic) {
  const found = { linear: null, angular: null };
  const { subscribers } = await callRosapi('/rosapi/subscribers', { topic });
  for (const node of subscribers) {
    for (const [kind, names] of Object.entries(LIMIT_PARAMS)) {
      for (const name of names) {
        if (found[kind] !== null) break;
        try {
          const v = JSON.parse((await callRosapi('/rosapi/get_param', { name: `${node}:${name}`, default_value: 'null' })).value);
          if (typeof v === 'number' && v > 0) found[kind] = v;
        } catch { /* not this one */ }
      }
    }
  }
  return found;
}

async function applyLimits() {
  state.limits = await robotLimits($('#topic').value.trim()).catch(() => ({ linear: null, angular: null }));
  const slider = $('#maxspeed');
  const max = state.limits.linear ?? 1.0;
  slider.max = String(max);
  if (Number(slider.value) > max) slider.value = String(max);
  $('#maxspeed-out').textContent = t('teleop.speed', { v: num(maxSpeed(), 2) });
  $('#limits').textContent = !state.limits.linear ? ''
    : state.limits.angular ? t('teleop.limits.both', { v: num(state.limits.linear), w: num(state.limits.angular) })
      : t('teleop.limits', { v: num(state.limits.linear) });
}

// Stops and disables driving while this page has no robot of its own ('' enables it again, and
// says what still stands: another's lease, the teacher's stop, a release — its notice may have
// come while the page was blocked).
function block(reason) {
  if (reason && state.timer) stopAll();
  state.blocked = reason;
  showNotice(reason || state.robotNs?.banner() || state.robotNs?.whyNot() || '');
}

// ---- driving ---------------------------------------------------------------------
function maxSpeed() { return Number($('#maxspeed').value); }

function command() {
  const k = state.keys;
  let lin = 0, ang = 0;
  if (state.joy.active) { lin = state.joy.y; ang = -state.joy.x; }
  else if (state.pad.active) { lin = state.pad.y; ang = -state.pad.x; }
  if (k.size) {
    lin = (k.has('up') ? 1 : 0) - (k.has('down') ? 1 : 0);
    ang = (k.has('left') ? 1 : 0) - (k.has('right') ? 1 : 0);
  }
  const v = Math.min(maxSpeed(), state.limits.linear ?? Infinity);
  const w = Math.min(2 * v, state.limits.angular ?? Infinity);
  return { linear: lin * v, angular: ang * w };
}

function twist(lin, ang) {
  const type = $('#msgtype').value;
  const msg = zeroVelocity(type);
  const t = msg.twist ?? msg;
  t.linear.x = lin;
  t.angular.z = ang;
  if (msg.header) {
    const now = Date.now();
    msg.header.stamp = { sec: Math.floor(now / 1000), nanosec: (now % 1000) * 1e6 };
  }
  return msg;
}

function publish(lin, ang) {
  const ros = state.ros;
  if (!ros?.isConnected || state.blocked || state.robotNs.lost) return;
  const topic = $('#topic').value.trim();
  const type = $('#msgtype').value;
  if (state.advertised !== `${topic} ${type}`) {
    ros.callOnConnection({ op: 'advertise', topic, type, id: `advertise:${topic}:teleop` });
    state.advertised = `${topic} ${type}`;
  }
  ros.callOnConnection({ op: 'publish', topic, msg: twist(lin, ang), t: state.link.now() });   // stamped: docs/protocol.md
  state.published += 1;
  $('#cmd').textContent = t('teleop.cmd', { v: num(lin, 2), w: num(ang, 2) });
}

function active() { return state.joy.active || state.pad.active || state.keys.size > 0; }

// Starts the fixed-rate loop on the first input; stops it and sends zero when input ends.
function update() {
  if (active()) {
    if (!state.timer) {
      const tick = () => { const c = command(); publish(c.linear, c.angular); };
      tick();
      state.timer = setInterval(tick, 1000 / Number($('#rate').value));
    }
  } else if (state.timer) {
    clearInterval(state.timer);
    state.timer = null;
    publish(0, 0);
  }
}

function setupJoystick() {
  const joy = nipplejs.create({
    zone: $('#joystick'), mode: 'static', position: { left: '50%', top: '50%' },
    size: Math.min(220, $('#joystick').clientWidth * 0.7 || 200), color: '#8fb3ff', restOpacity: 0.8,
  });
  // publishing starts with the first deflection, not with the touch
  joy.on('move', (e) => {
    const v = e.data.vector ?? { x: 0, y: 0 };
    const f = Math.min(1, e.data.force ?? 1);
    const n = Math.hypot(v.x, v.y) || 1;
    state.joy.x = (v.x / n) * f;
    state.joy.y = (v.y / n) * f;
    if (f > 0.05) state.joy.active = true;      // the touch itself is no command
    update();
  });
  joy.on('end', () => { state.joy = { x: 0, y: 0, active: false }; update(); });
}

// A gamepad (gamepad.js): its left stick as the joystick's, within the same speed and limits, while
// its dead-man button is held; let go, unplugged or hidden, the page sends its zero as on a release.
function setupGamepad() {
  state.gamepad = watchGamepads({
    onInput: (pad) => { state.pad = pad; update(); },
    onPad: (name) => {
      $('#gamepad').hidden = !name;
      $('#gamepad').textContent = name ? t('teleop.gamepad', { name: name.replace(/\s*\(.*$/, '') }) : '';
    },
  });
}

const KEYMAP = { ArrowUp: 'up', KeyW: 'up', ArrowDown: 'down', KeyS: 'down', ArrowLeft: 'left', KeyA: 'left', ArrowRight: 'right', KeyD: 'right' };

function setupKeys() {
  addEventListener('keydown', (e) => {
    if (e.target.matches?.('input:not([type=range]), select, textarea')) return;   // typing, not driving
    if (e.code === 'Space') { stopAll(); e.preventDefault(); return; }
    const k = KEYMAP[e.code];
    if (!k) return;
    e.preventDefault();
    state.keys.add(k);
    update();
  });
  addEventListener('keyup', (e) => { const k = KEYMAP[e.code]; if (k) { state.keys.delete(k); update(); } });
  for (const btn of document.querySelectorAll('#keys [data-key]')) {
    const k = btn.dataset.key;
    if (k === 'stop') { btn.addEventListener('pointerdown', stopAll); continue; }
    btn.addEventListener('pointerdown', (e) => { btn.setPointerCapture(e.pointerId); btn.classList.add('on'); state.keys.add(k); update(); });
    const up = () => { btn.classList.remove('on'); state.keys.delete(k); update(); };
    btn.addEventListener('pointerup', up);
    btn.addEventListener('pointercancel', up);
  }
  const out = () => { $('#maxspeed-out').textContent = t('teleop.speed', { v: num(maxSpeed(), 2) }); };
  $('#maxspeed').addEventListener('input', out);
  out();
  $('#cmd').textContent = t('teleop.cmd', { v: num(0, 2), w: num(0, 2) });
  $('#rate').addEventListener('change', () => { if (state.timer) { clearInterval(state.timer); state.timer = null; update(); } });
  $('#topic').addEventListener('change', () => { stopAll(); state.advertised = ''; });
}

function stopAll() {
  state.keys.clear();
  state.joy = { x: 0, y: 0, active: false };
  state.gamepad?.stop();   // held, the pad drives again only after its button is let go
  if (state.timer) { clearInterval(state.timer); state.timer = null; }
  if (state.advertised) publish(0, 0);   // a topic this page never drove gets nothing (the root
}                                        // /cmd_vel before the page reloads into its station)

addEventListener('pagehide', () => { if (state.timer) stopAll(); });
document.addEventListener('visibilitychange', () => { if (document.hidden && state.timer) stopAll(); });
addEventListener('blur', () => { if (state.keys.size) { state.keys.clear(); update(); } });

// ---- what the robot reports ----------------------------------------------------
const dash = { gauges: {}, history: null, series: {} };
const GRAPH_EVERY = 10000;   // ms between looks at the graph for what the robot has

function resubscribe() {
  for (const s of state.subs) s.close();
  state.subs = [];
  if (!state.ros?.isConnected) return;
  const has = (t) => state.present.has(t);
  const battery = $('#battery-topic').value.trim(), odom = withNamespace(state.robotNs.get(), '/odom');
  if (has(battery)) subscribe(battery, 'sensor_msgs/msg/BatteryState', showBattery, { throttle_rate: 500, queue_length: 1 });
  dash.board.subscribe(subscribe);
  cam.sub = null;
  if (has($('#camera-topic').value.trim())) subscribeCamera();
  for (const s of dash.history.series) if (s.topic) subscribePlot(s);
  if (has(odom)) subscribe(odom, 'nav_msgs/msg/Odometry', (m) => home.odom(m), { throttle_rate: 200, queue_length: 1 });
}

// The camera as the link sustains it: the subscribe extension `image` asks the gateway for a
// smaller JPEG (a gateway without it sends the original). Each frame's lag (arrival minus its
// header stamp, less the smallest lag seen: the clocks' offset) steers the size: down a step when
// frames arrive late, up again after a long run of fresh ones. A step up is tried no sooner than
// `upWait` after the last change, and a step up the link could not carry doubles that wait (up to
// 10 min): a home line is not probed every half minute, a school's LAN soon gets the full size.
const CAMERA_SIZES = [{ width: 640, quality: 70 }, { width: 320, quality: 60 }, { width: 160, quality: 50 }];
const cam = { size: 1, sub: null, minLag: Infinity, late: [], fresh: 0, changedAt: Date.now(), upAt: 0, upWait: 30000 };

function subscribeCamera() {
  if (cam.sub) { cam.sub.close(); state.subs = state.subs.filter((s) => s !== cam.sub); }
  Object.assign(cam, { minLag: Infinity, late: [], fresh: 0 });
  cam.sub = subscribe($('#camera-topic').value, 'sensor_msgs/msg/CompressedImage', showImage,
    { throttle_rate: 150, queue_length: 1, image: CAMERA_SIZES[cam.size] });
}

function frameAge(msg) {
  const st = msg.header?.stamp;
  if (!st || !st.sec) return null;
  const lag = Date.now() / 1000 - (st.sec + (st.nanosec || 0) / 1e9);
  cam.minLag = Math.min(cam.minLag, lag);
  const age = lag - cam.minLag;   // what the link adds, whatever the clocks' offset
  cam.late.push(age);
  if (cam.late.length > 5) cam.late.shift();
  const median = [...cam.late].sort((a, b) => a - b)[cam.late.length >> 1];
  cam.fresh = age < 0.25 ? cam.fresh + 1 : 0;
  const now = Date.now();
  if (cam.late.length === 5 && median > 0.6 && cam.size < CAMERA_SIZES.length - 1) {
    if (cam.upAt && now - cam.upAt < 2 * cam.upWait) cam.upWait = Math.min(2 * cam.upWait, 600000);
    cam.size += 1; cam.changedAt = now; cam.upAt = 0; subscribeCamera();
  } else if (cam.fresh > 50 && cam.size > 0 && now - cam.changedAt > cam.upWait) {
    cam.size -= 1; cam.changedAt = now; cam.upAt = now; subscribeCamera();
  }
  return Math.abs(cam.minLag) < 1 ? lag : age;   // clocks that agree: the true age
}

function showBattery(msg) {
  state.battery = msg;
  home.battery(msg);
  const pct = Number.isFinite(batteryPercent(msg)) ? batteryPercent(msg) : null;
  dash.gauges.battery.set(pct ?? NaN, batteryLevel(msg));
  if (dash.series.battery) dash.series.battery.last = pct;
  $('#battery-text').textContent = pct === null ? '?' : `${num(pct, 0)} %`;
  const v = Number.isFinite(msg.voltage) ? `${num(msg.voltage, 2)} V` : '';
  const a = Number.isFinite(msg.current) ? ` · ${num(msg.current, 2)} A` : '';
  $('#battery-info').textContent = v + a;
}

function showImage(msg) {
  const fmt = /png/i.test(msg.format) ? 'png' : 'jpeg';
  const data = typeof msg.data === 'string' ? msg.data : btoa(String.fromCharCode(...msg.data));
  $('#camera').src = `data:image/${fmt};base64,${data}`;
  state.frames += 1;
  const age = frameAge(msg);
  const size = CAMERA_SIZES[cam.size];
  $('#camera-info').textContent = t('teleop.camera.info', { n: state.frames, format: msg.format, px: size.width })
    + (age === null ? '' : t('teleop.camera.age', { ms: Math.max(0, Math.round(age * 1000)) }));
}

// A plotted field: {id, label, unit, topic, path, type, last}; also drives a gauge when named.
// subscribe: now (a plot added by hand), or not (applyGraph's, which resubscribe() subscribes).
function addSeries(spec, subscribeNow = true) {
  const s = { last: null, ...spec };
  dash.series[s.id] = s;
  dash.history.add(s);
  if (subscribeNow && s.topic && state.ros?.isConnected) subscribePlot(s);
  return s;
}

async function subscribePlot(s) {
  if (!state.present.has(s.topic)) {   // a topic asked for by name (the plot form): only if published
    const found = await publishedOf(callRosapi, [s.topic]).catch(() => new Set());
    if (!found.has(s.topic)) return;
    state.present.add(s.topic);
  }
  let type = s.type;
  if (!type) {
    try { type = (await callRosapi('/rosapi/topic_type', { topic: s.topic })).type; } catch { type = ''; }
  }
  subscribe(s.topic, type || undefined, (msg) => {
    let v;
    try { v = Number(field(msg, s.path)); } catch { return; }
    if (!Number.isFinite(v)) return;
    v *= s.scale ?? 1;
    s.last = v;
    dash.gauges[s.id]?.set(v);
  }, { throttle_rate: 100, queue_length: 1 });
}

// The page's own gauges, with the limits the gateway's --gauges file gives their topics
function fixedGauges(ns) {
  const topics = fixedTopics(ns);
  const limits = (el) => fileLimits(dash.board.limits, topics[el], ns);
  dash.gauges.battery = gauge($('#g-battery'), { label: t('teleop.battery'), unit: '%', min: 0, max: 100, warn: 50, danger: 20, low: true, ...limits('#g-battery') });
  const temp = { unit: '°C', min: 20, max: 90, warn: 50, danger: 65, digits: 1 };
  dash.gauges.left = gauge($('#g-left'), { label: t('teleop.motor.left'), ...temp, ...limits('#g-left') });
  dash.gauges.right = gauge($('#g-right'), { label: t('teleop.motor.right'), ...temp, ...limits('#g-right') });
  for (const [el, topic] of Object.entries(topics)) $(el).dataset.topic = topic;
}

function setupDashboard() {
  dash.board = new Gauges($('#gauges'), () => Object.values(fixedTopics(state.robotNs.get())));
  state.gauges = dash.board;
  fixedGauges(state.robotNs.get());
  dash.history = new History($('#plot'), `rosgate.history:${state.robotNs.get() || '/'}`);
  state.history = dash.history;
  dash.history.bindPinch();
  const loadSpan = bindSpan({ select: $('#plot-span'), range: $('#plot-range'), day: $('#plot-day'), from: $('#plot-from'),
    to: $('#plot-to'), show: $('#plot-show'), csv: $('#plot-csv'), png: $('#plot-png') }, dash.history, () => [
    ...dash.history.series.filter((s) => s.topic && s.path).map((s) => ({ id: s.id, topic: s.topic, field: s.path, scale: s.scale })),
    { id: 'battery', topic: $('#battery-topic').value, field: 'percentage', scale: 100 }]);
  dash.loadSpan = loadSpan;
  loadSpan();
  setInterval(() => dash.history.sample(), SAMPLE_EVERY);
  setInterval(() => dash.history.save(), 5000);
  addEventListener('pagehide', () => dash.history.save());
  new ResizeObserver(() => dash.history.resize()).observe($('#plot'));
  $('#plot-add').addEventListener('submit', (e) => {
    e.preventDefault();
    const f = e.target;
    const topic = f.topic.value.trim(), path = f.field.value.trim();
    if (topic && path) addSeries({ id: `${topic} ${path}`, label: `${topic} ${path}`, unit: '', topic, path });
  });
  $('#battery-topic').addEventListener('change', () => lookAgain(true));
  $('#camera-topic').addEventListener('change', () => lookAgain(true));
  setInterval(lookAgain, GRAPH_EVERY);
}

// The page's own plots (the rover's motors and speed, the battery field's topic), each shown once
// the robot publishes its topic (applyGraph).
function fixedSeries(ns) {
  const at = (name) => withNamespace(ns, name);
  return [
    { id: 'left', label: t('teleop.motor.left'), unit: '°C', topic: at('/motor/left/temperature'), path: 'temperature', type: 'sensor_msgs/msg/Temperature' },
    { id: 'right', label: t('teleop.motor.right'), unit: '°C', topic: at('/motor/right/temperature'), path: 'temperature', type: 'sensor_msgs/msg/Temperature' },
    { id: 'speed', label: t('teleop.speed.label'), unit: 'm/s', topic: at('/odom'), path: 'twist.twist.linear.x', type: 'nav_msgs/msg/Odometry' },
    { id: 'battery', label: t('teleop.battery'), unit: '%' },
  ];
}

// The robot namespace and the driver lease: a change of robot reloads the page under it.
function setupRobot() {
  state.robotNs = bindNamespace({
    call: callRosapi,
    onChange: () => { stopAll(); document.body.dataset.reloading = 'true'; location.reload(); },   // (the mark: for tests)
    onError: (text) => { stopAll(); showNotice(text); },
    onState: () => banner(),
  });
  const ns = (name) => withNamespace(state.robotNs.get(), name);
  for (const el of ['#topic', '#battery-topic', '#camera-topic']) $(el).value = ns($(el).value);
  if (state.robotNs.get()) $('#twin-link').search = `?ns=${encodeURIComponent(state.robotNs.get())}`;
  setupTwinPanel(state.robotNs.get());
  bindDriverBadge(lease);
  state.robotNs.follow(lease);
  lease.addEventListener('refused', (e) => showNotice(t('page.refused', { why: e.detail })));
  lease.addEventListener('change', () => { if (!banner() && lease.state !== 'other' && !state.blocked) showNotice(''); });
  lease.addEventListener('stop', () => { stopAll(); showNotice(STOPPED); });
}

// The 3D panel: /twin of this robot in a frame, loaded only while shown, so that a phone draws
// no WebGL and opens no second connection until its student asks for the view.
function setupTwinPanel(ns) {
  const button = $('#twin-show'), frame = $('#twin-frame');
  button.addEventListener('click', () => {
    const show = frame.hidden;
    frame.hidden = !show;
    button.textContent = t(show ? 'teleop.hide' : 'teleop.show');
    button.setAttribute('aria-expanded', String(show));
    const q = new URLSearchParams({ embed: '1' });
    if (ns) q.set('ns', ns);
    if (params.get('url')) q.set('url', params.get('url'));
    frame.src = show ? `twin?${q}` : 'about:blank';
  });
}

// What holds this robot still until the student acts (released, stopped, no robot): said for as
// long as it holds, as the IDE's banner says it. Returns the text ('' : nothing holds it).
function banner() {
  const why = state.robotNs.banner();
  if (why) { if (state.timer || active()) stopAll(); showNotice(why); }
  if (state.robotNs.lost && state.advertised && state.ros?.isConnected) {   // not hers: leave it to the next student
    state.ros.callOnConnection({ op: 'unadvertise', topic: state.advertised.split(' ')[0], id: `advertise:${state.advertised.split(' ')[0]}:teleop` });
    state.advertised = '';
  }
  return why;
}

function showNotice(text) {
  $('#notice').textContent = text;
  $('#notice').hidden = !text;
  state.notice = text;
}

// the page's one module: the bar complete (Rec, Booking) before the joystick measures the page
state.recorder = mountRecorder();
state.booking = mountBooking();
setupRobot();
if (params.get('topic')) $('#topic').value = params.get('topic');
setupKeys();
setupJoystick();
setupGamepad();
setupDashboard();
connect();
document.body.dataset.ready = 'true';
