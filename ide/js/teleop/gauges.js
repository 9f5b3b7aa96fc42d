// Gauges by type: every sensor_msgs BatteryState and Temperature topic the robot has on the graph,
// and each joint's effort of its JointState topics, one gauge each, named by its topic (relative
// to the robot's namespace). Limits: the gateway's --gauges file first (GET api/gauges: a topic,
// a glob, or a name relative to the robot's namespace), then the robot's own message (a battery's
// health and charging state, its charge over its design capacity when it gives no percentage),
// then the page's defaults. A fixed gauge the page already has for a topic (the battery topic
// field, the rover's motors) is not drawn twice.
import { gauge } from './dashboard.js';
import { withNamespace } from '../../runtime/util.js';
import { normType, nameGlob } from '../robot/graph.js';
import { api } from '../link/api.js';

export const KINDS = {
  'sensor_msgs/msg/BatteryState': 'battery',
  'sensor_msgs/msg/Temperature': 'temperature',
  'sensor_msgs/msg/JointState': 'joints',
};
const DEFAULTS = {
  battery: { unit: '%', min: 0, max: 100, warn: 50, danger: 20, low: true },
  temperature: { unit: '°C', min: 20, max: 90, warn: 50, danger: 65, digits: 1 },
  effort: { unit: '', min: 0, max: 1, digits: 1, auto: true },
};
const MAX_JOINTS = 12;                // gauges per JointState topic (a humanoid's 30 joints: a plot, not gauges)
// BatteryState power_supply_health: OVERHEAT, DEAD, OVERVOLTAGE, UNSPEC_FAILURE, COLD, WATCHDOG_TIMER_EXPIRE, SAFETY_TIMER_EXPIRE
const UNHEALTHY = new Set([3, 4, 5, 6, 7, 8, 9]);
const CHARGING = 1, FULL = 4;          // power_supply_status

/** The limits the --gauges file gives a topic ({} when none): its exact name first, then a glob. */
export function fileLimits(limits, topic, ns) {
  const names = Object.keys(limits).map((k) => [k, k.startsWith('/') ? k : withNamespace(ns, `/${k}`)]);
  const exact = names.find(([, n]) => n === topic);
  if (exact) return limits[exact[0]];
  const glob = names.find(([, n]) => /[*?]/.test(n) && nameGlob(n).test(topic));
  return glob ? limits[glob[0]] : {};
}

/** The percentage a BatteryState says, or that its charge and (design) capacity give. */
export function batteryPercent(msg) {
  if (Number.isFinite(msg.percentage)) return msg.percentage * 100;
  const cap = Number.isFinite(msg.capacity) && msg.capacity > 0 ? msg.capacity : msg.design_capacity;
  return Number.isFinite(msg.charge) && cap > 0 ? (100 * msg.charge) / cap : NaN;
}

/** The level a BatteryState itself gives: danger when unhealthy, ok while charging or full. */
export function batteryLevel(msg) {
  if (UNHEALTHY.has(msg.power_supply_health)) return 'danger';
  if (msg.power_supply_status === CHARGING || msg.power_supply_status === FULL) return 'ok';
  return null;
}

export class Gauges {
  /** el: the gauges' container; fixed(): the topics the page's own gauges show already. */
  constructor(el, fixed) {
    this.el = el;
    this.fixed = fixed;
    this.limits = {};
    this.topics = [];     // [{topic, kind, type, gauges: Map}]
    this.ready = api('api/gauges')   // a gateway without the route: no limits
      .then((b) => { this.limits = b?.limits ?? {}; })
      .catch(() => {});
  }

  /** The gauges for what the graph has under the namespace ns; returns how many topics. */
  show(topics, types, ns) {
    const fixed = new Set(this.fixed());
    for (const t of this.topics) for (const g of t.gauges.values()) g.el.remove();
    this.topics = topics.map((topic, i) => ({ topic, type: normType(types[i]) }))
      .filter(({ topic, type }) => KINDS[type] && !fixed.has(topic) && (!ns || topic.startsWith(`${ns}/`)))
      .map(({ topic, type }) => ({ topic, type, kind: KINDS[type], gauges: new Map(), ns }));
    for (const t of this.topics) if (t.kind !== 'joints') this.add(t, '');
    return this.topics.length;
  }

  name(t, joint) {
    const rel = t.ns && t.topic.startsWith(`${t.ns}/`) ? t.topic.slice(t.ns.length + 1) : t.topic;
    return joint ? `${rel} ${joint}` : rel;
  }

  add(t, joint) {
    const el = document.createElement('div');
    el.dataset.topic = t.topic;
    el.dataset.kind = t.kind;
    if (joint) el.dataset.joint = joint;
    const label = this.name(t, joint);
    el.title = joint ? `${t.topic} ${joint}` : t.topic;
    const own = fileLimits(this.limits, t.topic, t.ns);
    const part = t.kind === 'joints' ? 'effort' : t.kind;
    const given = t.kind === 'joints' ? (own.effort ?? {}) : own;
    const opts = { ...DEFAULTS[part], ...given, label: label.length > 20 ? `…${label.slice(-19)}` : label };
    if ('max' in given) opts.auto = false;
    el.dataset.limits = JSON.stringify({ warn: opts.warn ?? null, danger: opts.danger ?? null, max: opts.max });
    this.el.append(el);
    const g = { el, gauge: gauge(el, opts) };
    t.gauges.set(joint, g);
    return g;
  }

  /** The history plots of the gauges' topics: a battery's percentage (in %), a temperature. */
  plots() {
    return this.topics.filter((t) => t.kind !== 'joints').map((t) => ({
      id: t.topic, label: this.name(t, ''), topic: t.topic, type: t.type, unit: DEFAULTS[t.kind].unit,
      ...(t.kind === 'battery' ? { path: 'percentage', scale: 100 } : { path: 'temperature' }),
    }));
  }

  /** Subscribes (through the page's subscribe) to every topic shown. */
  subscribe(subscribe) {
    for (const t of this.topics) {
      subscribe(t.topic, t.type, (msg) => this.message(t, msg), { throttle_rate: 500, queue_length: 1 });
    }
  }

  message(t, msg) {
    if (t.kind === 'battery') {
      const g = t.gauges.get('');
      g.gauge.set(batteryPercent(msg), batteryLevel(msg));
      g.el.dataset.charging = String(msg.power_supply_status === CHARGING);
    } else if (t.kind === 'temperature') {
      t.gauges.get('').gauge.set(Number(msg.temperature));
    } else {
      (msg.name ?? []).slice(0, MAX_JOINTS).forEach((joint, i) => {
        const effort = msg.effort?.[i];
        if (!Number.isFinite(effort)) return;
        (t.gauges.get(joint) ?? this.add(t, joint)).gauge.set(Math.abs(effort));
      });
    }
  }
}
