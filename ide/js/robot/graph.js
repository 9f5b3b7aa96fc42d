// What the live ROS graph offers, asked through rosapi and cached for the dropdowns.
// Every method answers from the cache at once; refresh() updates it in the background.

export function normType(t) {
  // 'pkg/Type' and 'pkg/msg/Type' name the same type
  const p = String(t || '').split('/');
  return p.length === 2 ? `${p[0]}/msg/${p[1]}` : String(t || '');
}

/** A glob of ROS names as a RegExp: `*` any characters but `/`, `?` one of them. */
export function nameGlob(glob) {
  return new RegExp(`^${String(glob).replace(/[.+^${}()|[\]\\]/g, '\\$&').replace(/\*/g, '[^/]*').replace(/\?/g, '[^/]')}$`);
}

/**
 * The topics among `names` that something publishes: what the robot has. The graph also lists a
 * topic that only has subscribers (ROS 2 does: a subscription is an endpoint of its topic), so a
 * page that looked for /odom on a turtle would find it there next time, and a model or a gauge
 * chosen by its name would be wrong. call(service, args) -> Promise of the reply's values.
 */
export async function publishedOf(call, names) {
  const unique = [...new Set(names.filter(Boolean))];
  const found = await Promise.all(unique.map((topic) => call('/rosapi/publishers', { topic })
    .then((r) => (r?.publishers?.length ? topic : null), () => null)));
  return new Set(found.filter(Boolean));
}

export class RosGraph extends EventTarget {
  constructor() {
    super();
    this.ros = null;
    this.topics = new Map();    // name -> type
    this.services = new Map();
    this.actions = new Map();
    this.typedefs = new Map();  // 'kind:type' -> typedefs[]
    this._refreshing = null;
    this.loaded = false;
  }

  setRos(ros) {
    this.ros = ros;
    this.loaded = false;         // true once refresh() has read this connection's graph
    this.typedefs.clear();
  }

  get connected() { return !!this.ros?.isConnected; }

  call(service, args = {}, timeout = 5000) {
    const ros = this.ros;
    if (!ros?.isConnected) return Promise.reject(new Error('not connected'));
    const id = `call_service:${service}:graph.${Math.random().toString(36).slice(2)}`;
    return new Promise((resolve, reject) => {
      const timer = setTimeout(() => { off(); reject(new Error(`${service}: no answer`)); }, timeout);
      const off = () => { clearTimeout(timer); ros.off(id, onReply); ros.off(`status:${id}`, onStatus); };
      const onReply = (m) => {
        off();
        if (m.result === false) reject(new Error(`${service}: ${m.values}`));
        else resolve(m.values);
      };
      const onStatus = (m) => { if (m.level === 'error') { off(); reject(new Error(m.msg)); } };
      ros.on(id, onReply);
      ros.on(`status:${id}`, onStatus);
      ros.callOnConnection({ op: 'call_service', id, service, args });
    });
  }

  refresh() {
    if (this._refreshing) return this._refreshing;
    const ros = this.ros;
    this._refreshing = (async () => {
      try {
        const t = await this.call('/rosapi/topics');
        this.topics = new Map(t.topics.map((n, i) => [n, t.types[i]]));
        const s = await this.call('/rosapi/services');
        const services = new Map();
        await Promise.all(s.services.map(async (name) => {
          const known = this.services.get(name);
          if (known) { services.set(name, known); return; }
          try {
            services.set(name, (await this.call('/rosapi/service_type', { service: name })).type);
          } catch { services.set(name, ''); }
        }));
        this.services = services;
        const a = await this.call('/rosapi/action_servers');
        const actions = new Map();
        await Promise.all(a.action_servers.map(async (name) => {
          const known = this.actions.get(name);
          if (known) { actions.set(name, known); return; }
          try {
            actions.set(name, (await this.call('/rosapi/action_type', { action: name })).type);
          } catch { actions.set(name, ''); }
        }));
        this.actions = actions;
        if (this.ros === ros) this.loaded = true;
        this.dispatchEvent(new Event('change'));
      } finally {
        this._refreshing = null;
      }
    })();
    return this._refreshing;
  }

  _map(kind) { return { topic: this.topics, service: this.services, action: this.actions }[kind]; }

  // The names of a kind, sorted. With a robot namespace `ns` (a station of a fleet) its own names
  // come first, written without it ('/turtle1/cmd_vel' for /s07/turtle1/cmd_vel: the generic
  // blocks put such a name in the page's station, see generators/scope.js), then the gateway's
  // other names, then the other stations' copies of the station's names.
  names(kind, ns = '') {
    const all = [...(this._map(kind)?.keys() ?? [])].sort();
    if (!ns) return all;
    const own = all.filter((n) => n.startsWith(`${ns}/`)).map((n) => n.slice(ns.length));
    const mine = new Set(own);
    const others = (n) => /^\/[^/]+(\/.+)$/.exec(n)?.[1];
    const rest = all.filter((n) => !n.startsWith(`${ns}/`));
    return [...own, ...rest.filter((n) => !mine.has(others(n))), ...rest.filter((n) => mine.has(others(n)))];
  }

  has(kind, name) { return !!this._map(kind)?.has(name); }

  typeOf(kind, name) { return this._map(kind)?.get(name) || ''; }

  // Resolves once the graph has been read since the page connected (at once when it has been),
  // or after `timeout` ms: a run's names are written with what the graph knows.
  ready(timeout = 3000) {
    if (this.loaded || !this.connected) return Promise.resolve();
    return Promise.race([this.refresh().catch(() => {}), new Promise((r) => setTimeout(r, timeout))]);
  }

  // All message types seen on topics (for the message block's type menu).
  messageTypes() {
    return [...new Set([...this.topics.values()].filter(Boolean))].sort();
  }

  serviceTypes() { return [...new Set([...this.services.values()].filter(Boolean))].sort(); }
  actionTypes() { return [...new Set([...this.actions.values()].filter(Boolean))].sort(); }

  // typedefs of a message ('msg'), a service request ('request') or an action goal ('goal').
  async details(kind, type) {
    const key = `${kind}:${type}`;
    if (this.typedefs.has(key)) return this.typedefs.get(key);
    const [service] = {
      msg: ['/rosapi/message_details'],
      request: ['/rosapi/service_request_details'],
      response: ['/rosapi/service_response_details'],
      goal: ['/rosapi/action_goal_details'],
      feedback: ['/rosapi/action_feedback_details'],
      result: ['/rosapi/action_result_details'],
    }[kind];
    const r = await this.call(service, { type });
    this.typedefs.set(key, r.typedefs);
    return r.typedefs;
  }

  cachedDetails(kind, type) { return this.typedefs.get(`${kind}:${type}`); }

  // Leaf field paths of a message type (for "latest [field] of topic"), from cache.
  fieldPaths(type) {
    const defs = this.cachedDetails('msg', type);
    if (!defs?.length) return [];
    const byType = new Map(defs.map((d) => [normType(d.type), d]));
    const out = [];
    const walk = (def, prefix, depth) => {
      def.fieldnames.forEach((name, i) => {
        const ft = def.fieldtypes[i];
        const sub = byType.get(normType(ft));
        const path = prefix ? `${prefix}.${name}` : name;
        if (sub && def.fieldarraylen[i] === -1 && depth < 4) walk(sub, path, depth + 1);
        else out.push(path);
      });
    };
    walk(defs[0], '', 0);
    return out;
  }
}

// The graph the blocks' dropdowns read and the scope their names are written in (generators/
// scope.js), set once by the page.
export const shared = { graph: null, scope: null };
