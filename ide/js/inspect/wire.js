// The /inspect page's calls over its one Link (link.js): services as promises, subscriptions that
// come back by themselves on every new connection, and publishing whose refusal the page hears.
// Everything goes through the gateway's rules like any client's op: a refusal (a viewer's set,
// another station's parameters) comes back as the call's failure or as a status naming the op's id.

const BARRIER = '/rosapi/get_time';   // the gateway answers ops in order: a refusal comes before this

export class Wire extends EventTarget {
  constructor(link) {
    super();
    this.link = link;
    this.seq = 0;
    this.subs = new Set();        // what is subscribed now (each is sent again on a new connection)
    this.advertised = new Map();  // topic -> type, on this connection
    this.statuses = new Map();    // op id -> fn(status): refusals of subscribes and publishes
    link.addEventListener('open', (e) => {
      this.advertised.clear();
      e.detail.on('status', (m) => { if (m.id && this.statuses.has(m.id)) this.statuses.get(m.id)(m); });
      for (const sub of this.subs) this._send(sub);
      this.dispatchEvent(new Event('open'));
    });
  }

  get connected() { return Boolean(this.link.ros?.isConnected); }

  _id(kind, name) { this.seq += 1; return `${kind}:${name}:inspect.${this.seq}`; }

  // A service's response values; rejects with the gateway's words (a refusal, a failed call).
  call(service, args = {}, { type, timeout = 15000 } = {}) {
    const ros = this.link.ros;
    if (!ros?.isConnected) return Promise.reject(new Error('not connected'));
    const id = this._id('call_service', service);
    return new Promise((resolve, reject) => {
      const timer = setTimeout(() => { ros.off(id, done); reject(new Error(`${service}: no answer`)); }, timeout);
      function done(m) {
        clearTimeout(timer);
        if (m.result === false) reject(new Error(typeof m.values === 'string' ? m.values : JSON.stringify(m.values)));
        else resolve(m.values ?? {});
      }
      ros.once(id, done);
      ros.callOnConnection({ op: 'call_service', id, service, args, ...(type ? { type } : {}) });
    });
  }

  // Calls onMsg(msg) for each message until close(); options: throttle_rate, queue_length, image,
  // points. onRefused(text): the gateway said no (name globs, roles, a wrong type).
  subscribe(topic, type, onMsg, options = {}, onRefused = () => {}) {
    const sub = { topic, type, onMsg, options, onRefused, id: this._id('subscribe', topic), ros: null, listener: null };
    this.subs.add(sub);
    this._send(sub);
    return { close: () => this._unsubscribe(sub) };
  }

  _send(sub) {
    const ros = this.link.ros;
    if (!ros?.isConnected) return;
    if (sub.ros && sub.listener) sub.ros.off(sub.topic, sub.listener);
    sub.ros = ros;
    sub.listener = (m) => sub.onMsg(m.msg);
    ros.on(sub.topic, sub.listener);
    this.statuses.set(sub.id, (m) => { if (m.level === 'error') sub.onRefused(m.msg); });
    ros.callOnConnection({ op: 'subscribe', id: sub.id, topic: sub.topic, ...(sub.type ? { type: sub.type } : {}), ...sub.options });
  }

  _unsubscribe(sub) {
    if (!this.subs.delete(sub)) return;
    this.statuses.delete(sub.id);
    if (sub.ros && sub.listener) sub.ros.off(sub.topic, sub.listener);
    if (sub.ros?.isConnected && sub.ros === this.link.ros) sub.ros.callOnConnection({ op: 'unsubscribe', id: sub.id, topic: sub.topic });
  }

  // Publishes one message; resolves once the gateway has taken it, rejects with its refusal.
  async publish(topic, type, msg) {
    const ros = this.link.ros;
    if (!ros?.isConnected) throw new Error('not connected');
    const id = this._id('publish', topic);
    let refused = null;
    this.statuses.set(id, (m) => { if (m.level === 'error') refused = m.msg; });
    try {
      if (this.advertised.get(topic) !== type) {
        ros.callOnConnection({ op: 'advertise', id: this._id('advertise', topic), topic, type });
        this.advertised.set(topic, type);
      }
      ros.callOnConnection({ op: 'publish', id, topic, msg, type });
      await this.call(BARRIER);
    } finally {
      this.statuses.delete(id);
    }
    if (refused) throw new Error(refused);
  }
}
