// The teleop page: joystick, keys and buttons publish a velocity at a fixed rate while
// held and zero on release; battery, camera and plots show what the robot reports.
import { Ros } from 'roslib';
import nipplejs from 'nipplejs';
import uPlot from 'uplot';
import { field, zeroVelocity, withNamespace } from '../runtime/util.js';
import { DriverLease, bindDriverBadge, DRIVER_TOPIC } from './driver.js';
import { bindNamespace, CLAIM_SERVICE } from './robotns.js';

const $ = (s) => document.querySelector(s);
const params = new URLSearchParams(location.search);
const state = {
  ros: null,
  joy: { x: 0, y: 0, active: false },
  keys: new Set(),
  timer: null,
  published: 0,
  advertised: '',
  battery: null,
  frames: 0,
  subs: [],
};
window.teleop = state;
const lease = new DriverLease();
state.lease = lease;

// ---- connection -----------------------------------------------------------
function setStatus(s, text) { const el = $('#status'); el.dataset.state = s; el.textContent = text; document.body.dataset.connection = s; }

function connect() {
  const url = params.get('url') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`
    + (params.get('name') ? `?name=${encodeURIComponent(params.get('name'))}` : '');
  const ros = new Ros({});
  state.ros = ros;
  state.advertised = '';
  setStatus('connecting', 'connecting…');
  ros.on('connection', () => { setStatus('connected', 'connected'); lease.attach(ros); onConnected(); });
  ros.on('close', () => {
    if (state.ros !== ros) return;
    setStatus('closed', 'disconnected');
    setTimeout(connect, 2000);
  });
  ros.on('error', () => setStatus('error', 'cannot connect'));
  ros.connect(url).catch(() => setStatus('error', 'bad URL'));
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
    const { topics, types } = await callRosapi('/rosapi/topics');
    if (topics.includes(DRIVER_TOPIC)) lease.watch();
    const ns = state.robotNs.get();
    const vel = topics.filter((t, i) => /geometry_msgs\/(msg\/)?Twist(Stamped)?$/.test(types[i])
      && (!ns || t.startsWith(`${ns}/`)));
    $('#topics').replaceChildren(...topics.map((t) => new Option(t, t)));
    const topicEl = $('#topic');
    if (!params.get('topic') && !vel.includes(topicEl.value) && vel.length) {
      const preferred = withNamespace(ns, '/cmd_vel');
      topicEl.value = vel.includes(preferred) ? preferred : vel[0];
    }
    const t = types[topics.indexOf(topicEl.value)];
    if (t) $('#msgtype').value = /Stamped$/.test(t) ? 'geometry_msgs/msg/TwistStamped' : 'geometry_msgs/msg/Twist';
    const { services } = await callRosapi('/rosapi/services');
    state.robotNs.claimable(services.includes(CLAIM_SERVICE));
  } catch { /* rosapi unavailable: keep the defaults */ }
  resubscribe();
}

// ---- driving ---------------------------------------------------------------------
function maxSpeed() { return Number($('#maxspeed').value); }

function command() {
  const k = state.keys;
  let lin = 0, ang = 0;
  if (state.joy.active) { lin = state.joy.y; ang = -state.joy.x; }
  if (k.size) {
    lin = (k.has('up') ? 1 : 0) - (k.has('down') ? 1 : 0);
    ang = (k.has('left') ? 1 : 0) - (k.has('right') ? 1 : 0);
  }
  const v = maxSpeed();
  return { linear: lin * v, angular: ang * 2 * v };
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
  if (!ros?.isConnected) return;
  const topic = $('#topic').value.trim();
  const type = $('#msgtype').value;
  if (state.advertised !== `${topic} ${type}`) {
    ros.callOnConnection({ op: 'advertise', topic, type, id: `advertise:${topic}:teleop` });
    state.advertised = `${topic} ${type}`;
  }
  ros.callOnConnection({ op: 'publish', topic, msg: twist(lin, ang) });
  state.published += 1;
  $('#cmd').textContent = `linear ${lin.toFixed(2)} m/s · angular ${ang.toFixed(2)} rad/s`;
}

function active() { return state.joy.active || state.keys.size > 0; }

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
  const out = () => { $('#maxspeed-out').textContent = `${maxSpeed().toFixed(2)} m/s`; };
  $('#maxspeed').addEventListener('input', out);
  out();
  $('#rate').addEventListener('change', () => { if (state.timer) { clearInterval(state.timer); state.timer = null; update(); } });
  $('#topic').addEventListener('change', () => { stopAll(); state.advertised = ''; });
}

function stopAll() {
  state.keys.clear();
  state.joy = { x: 0, y: 0, active: false };
  if (state.timer) { clearInterval(state.timer); state.timer = null; }
  publish(0, 0);
}

addEventListener('pagehide', () => { if (state.timer) stopAll(); });
document.addEventListener('visibilitychange', () => { if (document.hidden && state.timer) stopAll(); });
addEventListener('blur', () => { if (state.keys.size) { state.keys.clear(); update(); } });

// ---- what the robot reports ----------------------------------------------------
const plot = { series: [], data: [[]], chart: null, start: performance.now() / 1000 };

function resubscribe() {
  for (const s of state.subs) s.close();
  state.subs = [];
  subscribe($('#battery-topic').value, 'sensor_msgs/msg/BatteryState', showBattery, { throttle_rate: 500, queue_length: 1 });
  subscribe($('#camera-topic').value, 'sensor_msgs/msg/CompressedImage', showImage, { throttle_rate: 200, queue_length: 1 });
  for (const s of plot.series) subscribePlot(s);
}

function showBattery(msg) {
  state.battery = msg;
  const pct = Number.isFinite(msg.percentage) ? msg.percentage * 100 : null;
  const el = $('#battery');
  $('#battery-fill').style.width = `${Math.max(0, Math.min(100, pct ?? 0))}%`;
  el.dataset.level = pct === null ? '' : pct < 20 ? 'low' : pct < 50 ? 'mid' : 'ok';
  $('#battery-text').textContent = pct === null ? '?' : `${pct.toFixed(0)} %`;
  const v = Number.isFinite(msg.voltage) ? `${msg.voltage.toFixed(2)} V` : '';
  const a = Number.isFinite(msg.current) ? ` · ${msg.current.toFixed(2)} A` : '';
  $('#battery-info').textContent = v + a;
}

function showImage(msg) {
  const fmt = /png/i.test(msg.format) ? 'png' : 'jpeg';
  const data = typeof msg.data === 'string' ? msg.data : btoa(String.fromCharCode(...msg.data));
  $('#camera').src = `data:image/${fmt};base64,${data}`;
  state.frames += 1;
  $('#camera-info').textContent = `${state.frames} frames · ${msg.format}`;
}

function addSeries(topic, path, type = '') {
  const s = { topic, path, type, label: `${topic} ${path}`, idx: plot.series.length + 1, last: null };
  plot.series.push(s);
  plot.data.push(plot.data[0].map(() => null));
  buildChart();
  if (state.ros?.isConnected) subscribePlot(s);
}

async function subscribePlot(s) {
  let type = s.type;
  if (!type) {
    try { type = (await callRosapi('/rosapi/topic_type', { topic: s.topic })).type; } catch { type = ''; }
  }
  subscribe(s.topic, type || undefined, (msg) => {
    let v;
    try { v = Number(field(msg, s.path)); } catch { return; }
    if (!Number.isFinite(v)) return;
    s.last = v;
  }, { throttle_rate: 100, queue_length: 1 });
}

// One sample row per 200 ms with each series' latest value; a 30 s window.
function sample() {
  if (!plot.chart) return;
  const t = performance.now() / 1000 - plot.start;
  plot.data[0].push(t);
  plot.series.forEach((s, i) => plot.data[i + 1].push(s.last));
  while (plot.data[0].length && plot.data[0][0] < t - 30) for (const col of plot.data) col.shift();
  plot.chart.setData(plot.data);
}

function buildChart() {
  const el = $('#plot');
  plot.chart?.destroy();
  const colours = ['#ff7043', '#42a5f5', '#66bb6a', '#ab47bc', '#ffca28', '#26c6da'];
  plot.chart = new uPlot({
    width: Math.max(240, el.clientWidth),
    height: 200,
    scales: { x: { time: false } },
    axes: [{ stroke: '#aab3cc', grid: { stroke: '#2c3350' } }, { stroke: '#aab3cc', grid: { stroke: '#2c3350' } }],
    series: [{ label: 's' }, ...plot.series.map((s, i) => ({ label: s.label, stroke: colours[i % colours.length], width: 2, spanGaps: true }))],
  }, plot.data, el);
}

function setupPlots() {
  const ns = (name) => withNamespace(state.robotNs.get(), name);
  addSeries(ns('/motor/left/temperature'), 'temperature', 'sensor_msgs/msg/Temperature');
  addSeries(ns('/motor/right/temperature'), 'temperature', 'sensor_msgs/msg/Temperature');
  addSeries(ns('/odom'), 'twist.twist.linear.x', 'nav_msgs/msg/Odometry');
  setInterval(sample, 200);
  new ResizeObserver(() => plot.chart?.setSize({ width: Math.max(240, $('#plot').clientWidth), height: 200 })).observe($('#plot'));
  $('#plot-add').addEventListener('submit', (e) => {
    e.preventDefault();
    const f = e.target;
    if (f.topic.value && f.field.value) addSeries(f.topic.value.trim(), f.field.value.trim());
  });
  $('#battery-topic').addEventListener('change', resubscribe);
  $('#camera-topic').addEventListener('change', resubscribe);
}

// The robot namespace and the driver lease: a change of robot reloads the page under it.
function setupRobot() {
  state.robotNs = bindNamespace({
    call: callRosapi,
    onChange: () => { stopAll(); location.reload(); },
    onError: (text) => showNotice(text),
  });
  const ns = (name) => withNamespace(state.robotNs.get(), name);
  for (const el of ['#topic', '#battery-topic', '#camera-topic']) $(el).value = ns($(el).value);
  bindDriverBadge(lease);
  lease.addEventListener('refused', (e) => showNotice(`Your commands are refused: ${e.detail}`));
  lease.addEventListener('change', () => { if (lease.state !== 'other') showNotice(''); });
}

function showNotice(text) {
  $('#notice').textContent = text;
  $('#notice').hidden = !text;
  state.notice = text;
}

setupRobot();
if (params.get('topic')) $('#topic').value = params.get('topic');
setupKeys();
setupJoystick();
setupPlots();
connect();
document.body.dataset.ready = 'true';
