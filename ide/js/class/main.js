// The teacher's view (/class): every robot station as a live tile — its world, whose station it
// is and who drives it, whether its program runs, the last error — with Stop, Release and the
// student's program (read-only). Owners come from the gateway's /rosgate/stations. Stations are the gateway's (the driver lease's list, else the fleet's, else the
// namespaces of the graph), so a real multi-robot graph shows the same way as the sim's fleet.
// Beside each student's tile, their newest kept runs (GET api/runs?all=1, an admin's: the class's)
// with their program, output and recording to download; and their exercises' best and last
// attempts with a "passed" mark (GET api/exercise-results: exercises.js). Below the tiles, the
// LMS courses' roster, known before a student first launches (GET api/roster: roster.js).
import { WorldView } from '../views/worldview.js';
import { DriverLease, DRIVER_TOPIC } from '../robot/driver.js';
import { isVelocityType, zeroVelocity, withNamespace } from '../../runtime/util.js';
import { showProgram } from './program.js';
import { STATIONS_TOPIC } from '../robot/robotns.js';
import { Link } from '../link/link.js';
import { mountBooking } from '../lab/booking.js';
import { t, tn } from '../i18n.js';
import { keptRuns, runItem } from '../lab/runhistory.js';
import { exerciseSummary, exerciseItem, exerciseTitles, showAttempts } from './exercises.js';
import { mountRoster } from './roster.js';

const $ = (s) => document.querySelector(s);
const REFRESH = 10000;   // ms between looks at the graph for new stations (and at the kept runs)
const TILE_RUNS = 3;     // a student's newest kept runs shown on their tile
// A tile's world at 2 Hz: the gateway merges the markers of each half second (newest of each wins,
// no change lost), so ten tiles fit a home line (docs/teacher.md)
const TILE_STREAM = { throttle_rate: 500, queue_length: 4 };
export const view = { titles: {}, ros: null, lease: new DriverLease(), tiles: new Map(), topics: [], types: [], services: [], owners: {}, seq: 0, runs: [], exercises: [] };

function setStatus(s, text) { const el = $('#status'); el.dataset.state = s; el.textContent = text; document.body.dataset.connection = s; }

function notice(text) { $('#notice').textContent = text; $('#notice').hidden = !text; }

function connect() {
  const params = new URLSearchParams(location.search);
  // deflate: the tiles' marker JSON shrinks about tenfold over a home line (gateway/web/socket.py)
  const url = params.get('url') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/?name=teacher&compression=deflate`;
  const link = new Link(url);
  view.link = link;
  setStatus('connecting', t('status.connecting'));
  link.addEventListener('open', (e) => {
    const ros = e.detail;
    view.ros = ros;
    setStatus('connected', t('status.connected'));
    view.lease.attach(ros);
    watchOwners(ros);
    for (const t of view.tiles.values()) t.attach(ros);
    refresh();
  });
  link.addEventListener('lost', () => { view.ros = null; setStatus('lost', t('status.lost')); });
  setInterval(() => { $('#link').textContent = link.describe(); }, 500);
  link.start();
}

// Who owns each station (a person: the signed-in name, or a browser), as the gateway announces it.
function watchOwners(ros) {
  ros.on(STATIONS_TOPIC, (m) => {
    if (view.ros !== ros) return;
    try { view.owners = JSON.parse(m.msg.data).owners ?? {}; } catch { view.owners = {}; }
    for (const t of view.tiles.values()) t.show();
  });
  ros.callOnConnection({ op: 'subscribe', id: `subscribe:${STATIONS_TOPIC}:class`, topic: STATIONS_TOPIC, type: 'std_msgs/msg/String' });
}

function call(service, args = {}) {
  const ros = view.ros;
  const id = `call_service:${service}:class.${++view.seq}`;
  return new Promise((resolve, reject) => {
    ros.once(id, (m) => (m.result === false ? reject(new Error(m.values)) : resolve(m.values)));
    ros.callOnConnection({ op: 'call_service', id, service, args });
  });
}

// The stations: the lease's list, else the fleet's parameter, else top namespaces with a world
// view of their own or a velocity topic (two or more of them); else the one robot of the gateway
// ('/': turtlesim's /turtle1/cmd_vel and /world/markers are one robot, not two stations).
async function stations() {
  if (view.lease.info?.stations?.length) return view.lease.info.stations;
  try {
    const v = JSON.parse((await call('/rosapi/get_param', { name: '/fleet:namespaces', default_value: 'null' })).value);
    if (Array.isArray(v) && v.length) return v;
  } catch { /* no fleet */ }
  const tops = new Set();
  let root = false;
  view.topics.forEach((t, i) => {
    const parts = t.split('/').filter(Boolean);
    const world = t.endsWith('/world/markers');
    if (!world && !isVelocityType(view.types[i])) return;
    if (parts.length > (world ? 2 : 1)) tops.add(`/${parts[0]}`);
    else root = true;
  });
  if (tops.size > 1) return [...tops].sort();
  return root ? ['/'] : [...tops];
}

async function refresh() {
  try {
    ({ topics: view.topics, types: view.types } = await call('/rosapi/topics'));
    ({ services: view.services } = await call('/rosapi/services'));
    if (view.topics.includes(DRIVER_TOPIC)) view.lease.watch();
    await show(await stations());
    for (const t of view.tiles.values()) { t.look(); t.show(); }
  } catch (e) { notice(t('class.graph.failed', { error: e.message })); }
}

async function show(list) {
  for (const ns of list) if (!view.tiles.has(ns)) view.tiles.set(ns, new Tile(ns));
  const tiles = [...view.tiles.values()].sort((a, b) => a.ns.localeCompare(b.ns));
  $('#tiles').replaceChildren(...tiles.map((t) => t.el));
  $('#count').textContent = tn('class.count', tiles.length) + (view.lease.available ? '' : t('class.no.lease'));
  if (!tiles.length) notice(t('class.no.stations'));
  else notice('');
  document.body.dataset.tiles = String(tiles.length);
}

class Tile {
  constructor(ns) {
    this.ns = ns;
    this.el = $('#tile').content.firstElementChild.cloneNode(true);
    this.el.dataset.ns = ns;
    this.el.querySelector('.ns').textContent = ns;
    this.world = new WorldView(this.el.querySelector('.world'), withNamespace(ns, '/world/markers'), { stream: TILE_STREAM });
    this.report = null;
    this.el.querySelector('.stop').onclick = () => stop(ns);
    this.el.querySelector('.release').onclick = () => release(ns);
    this.el.querySelector('.open').onclick = async () => { view.programShown = await showProgram(this.report, ns); };
    this.ros = null;
    if (view.ros?.isConnected) this.attach(view.ros);
    this.show();
  }

  attach(ros) {
    this.ros = ros;
    this.reporting = false;
    this.world.attach(ros);
    this.look();
  }

  // What the station has, subscribed once it is on the graph (a subscription would put it there):
  // its world and map, and the report of its IDE's program (there once a student's page reports).
  look() {
    const ros = this.ros;
    if (!ros?.isConnected) return;
    this.world.look(call);
    const topic = withNamespace(this.ns, '/rosgate/program');
    if (this.reporting || !view.topics.includes(topic)) return;
    this.reporting = true;
    ros.on(topic, (m) => {
      if (this.ros !== ros) return;
      try { this.report = JSON.parse(m.msg.data); } catch { this.report = null; }
      this.show();
    });
    ros.callOnConnection({ op: 'subscribe', id: `subscribe:${topic}:class`, topic, type: 'std_msgs/msg/String' });
  }

  show() {
    const d = view.lease.holderOf(this.ns);
    const owner = view.owners[this.ns]?.name;
    const halted = view.lease.info?.halted?.[this.ns];
    // the present only: a free station shows no program (the last class's is gone), and a report
    // is shown only when it is the owner's (not what another student's page left on this station),
    // by the gateway's stamp of who sent it (rules/reports.py), never the report's own word
    const by = this.report?.by?.name;
    const r = (owner || d) && by && (!owner || by === owner) ? this.report : null;
    let text;
    if (d && (!owner || d.owner)) text = t('class.drives', { who: d.run && owner ? t('class.run.of', { owner }) : d.name });
    else if (d) text = t('class.station.driven', { owner, who: d.name });
    else if (owner) text = t(halted ? 'class.station.stopped' : 'class.station.idle', { owner });
    else text = t(halted ? 'class.free.stopped' : 'station.free');
    this.el.querySelector('.holder').textContent = text;
    this.el.toggleAttribute('data-held', Boolean(d));
    this.el.toggleAttribute('data-halted', Boolean(halted));
    this.el.dataset.owner = owner ?? '';
    const state = r?.state ?? 'none';
    this.el.dataset.state = state;
    this.el.querySelector('.state').textContent = (['none', 'idle', 'running', 'paused'].includes(state) ? t(`class.state.${state}`) : state);
    // a text program's running line (its Python or JavaScript), as its IDE reports it
    const at = r?.line && state !== 'idle' && state !== 'none' ? r.line : 0;
    this.el.querySelector('.program').textContent = !r?.name ? ''
      : at ? t('class.tile.program.line', { name: r.name, line: at }) : t('class.tile.program', { name: r.name });
    this.el.dataset.line = at ? String(at) : '';
    const err = this.el.querySelector('.error');
    err.textContent = r?.error ? t('class.last.error', { error: r.error }) : '';
    err.hidden = !r?.error;
    this.el.toggleAttribute('data-error', Boolean(r?.error));
    this.el.querySelector('.open').disabled = !r?.program;
    this.showRuns(owner);
  }

  // the owner's newest kept runs (a free station: none)
  showRuns(owner) {
    const runs = owner ? view.runs.filter((run) => run.owner === owner).slice(0, TILE_RUNS) : [];
    const list = this.el.querySelector('.runs');
    list.replaceChildren(...runs.map(runItem));
    list.hidden = !runs.length;
    list.setAttribute('aria-label', t('class.runs'));
    this.el.dataset.runs = String(runs.length);
    this.showExercises(owner);
  }

  // the owner's best and last attempt of each exercise
  showExercises(owner) {
    const entries = owner ? view.exercises.filter((e) => e.name === owner) : [];
    const list = this.el.querySelector('.exercises');
    list.replaceChildren(...entries.map((e) => exerciseItem(e, view.titles)));
    list.hidden = !entries.length;
    list.setAttribute('aria-label', t('class.ex.label'));
    this.el.dataset.passed = String(entries.filter((e) => e.best.passed).length);
  }
}

// The kept runs this page's person may see (an admin: everyone's), newest first.
async function refreshRuns() {
  try { view.exercises = await exerciseSummary(); } catch { view.exercises = []; }   // not signed in: none
  if (view.exercises.length) view.titles = await exerciseTitles();
  showAttempts($('#attempts'), view.exercises, view.titles);
  try { view.runs = await keptRuns(); } catch { view.runs = []; }   // runs off, or not signed in: no list
  for (const tile of view.tiles.values()) tile.showRuns(view.owners[tile.ns]?.name);
}

// Stop: the gateway zeroes the station's commands, frees it and tells its pages to stop their
// programs (driver lease); without the lease this page publishes the zero commands itself.
function stop(ns) {
  if (view.lease.available) {
    view.lease.command(`stop ${ns}`);
    return;
  }
  view.topics.forEach((topic, i) => {
    const type = view.types[i];
    if ((ns !== '/' && !topic.startsWith(`${ns}/`)) || !isVelocityType(type)) return;
    view.ros.callOnConnection({ op: 'advertise', topic, type, id: `advertise:${topic}:class` });
    view.ros.callOnConnection({ op: 'publish', topic, msg: zeroVelocity(type) });
  });
}

// Release: on a fleet the gateway frees the claim, the lease and a stop in one step, and the
// student's pages keep off it until she claims again; elsewhere the lease alone is freed.
function release(ns) {
  if (view.services.includes(`${ns}/fleet/release`)) call(`${ns}/fleet/release`).catch((e) => notice(t('class.release.failed', { ns, error: e.message })));
  else if (view.lease.available) view.lease.command(`release ${ns}`);
}

// A station in use: someone's, driven, or running a program. Stop all leaves the others ready
// (a stop would hold until Take, and the next student to claim one would find it stopped).
function inUse(tile) {
  const ns = tile.ns;
  return Boolean(view.owners[ns] || view.lease.holderOf(ns) || ['running', 'paused'].includes(tile.report?.state));
}

function setup() {
  view.lease.addEventListener('change', () => {
    for (const t of view.tiles.values()) t.show();
    const listed = view.lease.info?.stations ?? [];
    if (listed.some((ns) => !view.tiles.has(ns))) show(listed);
  });
  $('#stop-all').onclick = () => { for (const t of view.tiles.values()) if (inUse(t)) stop(t.ns); };
  $('#release-all').onclick = () => {
    if (!confirm(t('class.releaseall.confirm'))) return;
    if (view.services.includes('/fleet/release_all')) call('/fleet/release_all').catch((e) => notice(t('class.releaseall.failed', { error: e.message })));
    else if (view.lease.available) for (const ns of view.tiles.keys()) view.lease.command(`release ${ns}`);
  };
  setInterval(() => { if (view.ros?.isConnected) refresh(); }, REFRESH);
  setInterval(refreshRuns, REFRESH);
  refreshRuns();
  const roster = mountRoster($('#roster'));
  setInterval(roster, REFRESH);
  roster();
}

setup();
connect();
view.booking = mountBooking();   // the page's one module mounts the bar's Booking too
document.body.dataset.ready = 'true';
