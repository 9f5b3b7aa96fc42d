// Who is driving: the gateway's driver lease (rosgate --exclusive-control), one per robot (fleet
// station, robot namespace or --control-glob group). /rosgate/driver (latched JSON) names the
// holders; "take NS" / "release NS" on /rosgate/control ask for one; the holder learns its own
// client id from the status info the gateway sends it on grant. When an admin stops this page's
// station (/class), a 'stop' event tells the page to stop its program; the stop holds (the
// announcement's "halted") until the station's owner presses Take. A holder that is the station's
// owner's other client (her robot-side run) is 'yours' to a page on its own station.
import { normNamespace } from '../../runtime/util.js';
import { t, time } from '../i18n.js';

export const DRIVER_TOPIC = '/rosgate/driver';
const CONTROL_TOPIC = '/rosgate/control';
const STRING = 'std_msgs/msg/String';
const HOLDER = /you hold the driver lease as client (\d+)/;
const REPORT = /^publish(?: \(id [^)]*\))?: [^:\s]*\/rosgate\/program: /;
const REFUSED = /^publish(?: \(id [^)]*\))?: [^:\s]+: (.* (?:is driving|stopped|released|station)\b.*)$/s;

// The lease group of a robot namespace, given the gateway's announcement.
export function groupOf(ns, info) {
  const n = normNamespace(ns);
  if (!n || !info) return '/';
  const top = `/${n.split('/')[1]}`;
  if (info.stations?.includes(top)) return top;
  if (info.drivers && n in info.drivers) return n;
  return '/';
}

export class DriverLease extends EventTarget {
  constructor() {
    super();
    this.ros = null;
    this.ns = '';
    this.ownStation = false;    // this page's namespace is its person's own station (robotns.js)
  }

  // A new connection: nothing known until watch() finds the lease.
  attach(ros) {
    if (this.ros) this.ros.off('status', this._onStatus);
    this.ros = ros;
    this.available = false;     // the gateway has a driver lease
    this.info = null;           // the last announcement: {driver, drivers, stations, stopped}
    this.driver = null;         // the holder of this page's group: {client, name, role, remote, since} or null
    this.me = null;             // this connection's client id, once it has held the lease
    this.advertised = false;
    this.watching = false;
    this._onStatus = (m) => this._status(m);
    ros.on('status', this._onStatus);
    ros.callOnConnection({ op: 'set_level', level: 'info' });
    this._changed();
  }

  // The robot namespace this page drives.
  setNamespace(ns) {
    this.ns = normNamespace(ns);
    this._update();
  }

  get group() { return groupOf(this.ns, this.info); }

  // Subscribes to the driver topic (call it once the graph lists it).
  watch() {
    const ros = this.ros;
    if (!ros || this.watching) return;
    this.watching = true;
    ros.on(DRIVER_TOPIC, (m) => {
      if (this.ros !== ros) return;
      let info;
      try { info = JSON.parse(m.msg.data); } catch { info = { driver: null }; }
      const before = this.info?.stopped?.[groupOf(this.ns, info)];
      const first = !this.available;
      this.info = info;
      this.available = true;
      this._update();
      const now = info.stopped?.[this.group];
      if (!first && now && now !== before) this.dispatchEvent(new CustomEvent('stop', { detail: this.group }));
    });
    ros.callOnConnection({ op: 'subscribe', id: `subscribe:${DRIVER_TOPIC}:lease`, topic: DRIVER_TOPIC, type: STRING });
  }

  // The holder of a namespace's group (null: free).
  holderOf(ns) {
    const g = groupOf(ns, this.info);
    return (g === '/' ? this.info?.driver : this.info?.drivers?.[g]) ?? null;
  }

  // 'off' (no lease on this gateway), 'nobody', 'you', 'yours' (your run, or another page of yours
  // on your own station) or 'other'
  get state() {
    if (!this.available) return 'off';
    if (!this.driver) return 'nobody';
    if (this.driver.client === this.me) return 'you';
    return this.driver.owner && this.ownStation ? 'yours' : 'other';
  }

  get label() {
    const state = this.state;
    if (state === 'yours') return this.driver.run ? t('driver.your.run', { run: this.driver.run }) : t('driver.you.other.page');
    return { off: '', nobody: t('page.nobody'), you: t('driver.you') }[state] ?? this.driver.name ?? t('driver.client', { n: this.driver.client });
  }

  // Whether the teacher's stop of this page's robot still holds (until Take).
  get halted() { return Boolean(this.info?.halted?.[this.group]); }

  take() { this.command(this.group === '/' ? 'take' : `take ${this.group}`); }
  release() { this.command(this.group === '/' ? 'release' : `release ${this.group}`); }

  // Publishes one control word ("take /s01", "stop /s02", ...).
  command(word) {
    const ros = this.ros;
    if (!ros?.isConnected) return;
    if (!this.advertised) {
      ros.callOnConnection({ op: 'advertise', id: `advertise:${CONTROL_TOPIC}:lease`, topic: CONTROL_TOPIC, type: STRING });
      this.advertised = true;
    }
    ros.callOnConnection({ op: 'publish', topic: CONTROL_TOPIC, msg: { data: word } });
  }

  _update() {
    if (this.available) this.driver = this.holderOf(this.ns);
    this._changed();
  }

  _status(m) {
    const held = HOLDER.exec(m.msg ?? '');
    if (held) {
      this.me = Number(held[1]);
      this._changed();
      return;
    }
    // (a program report refused on a station that is not this person's is no refused command)
    const refused = m.level === 'error' && !REPORT.test(m.msg ?? '') && REFUSED.exec(m.msg ?? '');
    if (refused) this.dispatchEvent(new CustomEvent('refused', { detail: refused[1] }));
  }

  _changed() { this.dispatchEvent(new Event('change')); }
}

// Binds the "driving: …" badge and its Take / Release buttons (#driver, #driver-name, #take, #release).
export function bindDriverBadge(lease, $ = (s) => document.querySelector(s)) {
  const show = () => {
    const state = lease.state;
    $('#driver').hidden = state === 'off';
    $('#driver').dataset.state = state;
    $('#driver-name').textContent = lease.label;
    const d = lease.driver;
    const where = lease.group === '/' ? '' : ` ${lease.group}`;
    $('#driver').title = d ? t('driver.title', { n: d.client, role: d.role ? ` (${d.role})` : '', remote: d.remote, since: time(d.since * 1000) }) + where : where.trim();
    $('#take').hidden = state === 'you';
    $('#release').hidden = state !== 'you';
  };
  lease.addEventListener('change', show);
  $('#take').onclick = () => lease.take();
  $('#release').onclick = () => lease.release();
  show();
}
