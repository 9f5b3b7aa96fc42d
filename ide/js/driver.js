// Who is driving: the gateway's driver lease (rosgate --exclusive-control). /rosgate/driver
// (latched JSON) names the holder; "take" / "release" on /rosgate/control ask for it; the
// holder learns its own client id from the status info the gateway sends it on grant.
export const DRIVER_TOPIC = '/rosgate/driver';
const CONTROL_TOPIC = '/rosgate/control';
const STRING = 'std_msgs/msg/String';
const HOLDER = /you hold the driver lease as client (\d+)/;
const REFUSED = /^publish(?: \(id [^)]*\))?: [^:\s]+: (.* is driving .*)$/s;

export class DriverLease extends EventTarget {
  constructor() {
    super();
    this.ros = null;
  }

  // A new connection: nothing known until watch() finds the lease.
  attach(ros) {
    if (this.ros) this.ros.off('status', this._onStatus);
    this.ros = ros;
    this.available = false;     // the gateway has a driver lease
    this.driver = null;         // {client, name, role, remote, since} or null
    this.me = null;             // this connection's client id, once it has held the lease
    this.advertised = false;
    this.watching = false;
    this._onStatus = (m) => this._status(m);
    ros.on('status', this._onStatus);
    ros.callOnConnection({ op: 'set_level', level: 'info' });
    this._changed();
  }

  // Subscribes to the driver topic (call it once the graph lists it).
  watch() {
    const ros = this.ros;
    if (!ros || this.watching) return;
    this.watching = true;
    ros.on(DRIVER_TOPIC, (m) => {
      if (this.ros !== ros) return;
      try { this.driver = JSON.parse(m.msg.data).driver ?? null; } catch { this.driver = null; }
      this.available = true;
      this._changed();
    });
    ros.callOnConnection({ op: 'subscribe', id: `subscribe:${DRIVER_TOPIC}:lease`, topic: DRIVER_TOPIC, type: STRING });
  }

  // 'off' (no lease on this gateway), 'nobody', 'you' or 'other'
  get state() {
    if (!this.available) return 'off';
    if (!this.driver) return 'nobody';
    return this.driver.client === this.me ? 'you' : 'other';
  }

  get label() {
    return { off: '', nobody: 'nobody', you: 'you' }[this.state] ?? this.driver.name ?? `client ${this.driver.client}`;
  }

  take() { this._command('take'); }
  release() { this._command('release'); }

  _command(word) {
    const ros = this.ros;
    if (!ros?.isConnected) return;
    if (!this.advertised) {
      ros.callOnConnection({ op: 'advertise', id: `advertise:${CONTROL_TOPIC}:lease`, topic: CONTROL_TOPIC, type: STRING });
      this.advertised = true;
    }
    ros.callOnConnection({ op: 'publish', topic: CONTROL_TOPIC, msg: { data: word } });
  }

  _status(m) {
    const held = HOLDER.exec(m.msg ?? '');
    if (held) {
      this.me = Number(held[1]);
      this._changed();
      return;
    }
    const refused = m.level === 'error' && REFUSED.exec(m.msg ?? '');
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
    $('#driver').title = d ? `client ${d.client}${d.role ? ` (${d.role})` : ''} from ${d.remote}, since ${new Date(d.since * 1000).toLocaleTimeString()}` : '';
    $('#take').hidden = state === 'you';
    $('#release').hidden = state !== 'you';
  };
  lease.addEventListener('change', show);
  $('#take').onclick = () => lease.take();
  $('#release').onclick = () => lease.release();
  show();
}
