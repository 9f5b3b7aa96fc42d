// The topics of the graph (in the robot's namespace, or all), with their types, how many nodes
// publish and subscribe to each, and their rate and bandwidth as the gateway measures them
// (/rosgate/topic_stats: bridge/topicstats.py). Only the rows in view are measured and counted:
// the page asks each second for those alone, and not at all while the tab is hidden, so a list of
// forty topics costs the robot what the five on a phone's screen cost.
import { t, num } from '../i18n.js';

export const STATS = '/rosgate/topic_stats';
const STATS_EVERY = 1000;     // ms between asks for the rows in view
const COUNTS_EVERY = 5000;    // ms between counts of a row's publishers and subscribers

export function rate(hz) {
  if (!(hz >= 0)) return '–';
  return t('inspect.hz', { v: num(hz, hz >= 100 ? 0 : hz >= 10 ? 1 : 2) });
}

export function bandwidth(bps) {
  if (!(bps >= 0)) return '–';
  const [v, unit] = bps >= 1e6 ? [bps / 1e6, 'MB'] : bps >= 1e3 ? [bps / 1e3, 'KB'] : [bps, 'B'];
  return t('inspect.bps', { v: num(v, v >= 100 ? 0 : 1), unit });
}

export class TopicList extends EventTarget {
  constructor(wire, els) {
    super();
    this.wire = wire;
    this.els = els;              // {root, body, filter, count}
    this.rows = new Map();       // topic -> {tr, type, cells, countedAt}
    this.visible = new Set();
    this.ns = '';
    this.types = new Map();
    this.stats = true;           // the gateway measures (a gateway without the service: no rates)
    this.observer = new IntersectionObserver((entries) => {
      for (const e of entries) {
        const topic = e.target.dataset.topic;
        if (e.isIntersecting) this.visible.add(topic); else this.visible.delete(topic);
      }
    });
    els.filter.addEventListener('input', () => this.render());
    setInterval(() => this.measure(), STATS_EVERY);
  }

  setNamespace(ns) { this.ns = ns; this.render(); }

  // topic -> type, from /rosapi/topics
  setTopics(types) {
    this.types = types;
    this.render();
  }

  shown() {
    const text = this.els.filter.value.trim().toLowerCase();
    return [...this.types].filter(([name, type]) => (!this.ns || name.startsWith(`${this.ns}/`))
      && (!text || name.toLowerCase().includes(text) || type.toLowerCase().includes(text)));
  }

  render() {
    const shown = this.shown();
    const keep = new Set(shown.map(([name]) => name));
    for (const [name, row] of this.rows) {
      if (!keep.has(name)) { this.observer.unobserve(row.tr); row.tr.remove(); this.rows.delete(name); this.visible.delete(name); }
    }
    let before = null;
    for (const [name, type] of shown.reverse()) {
      let row = this.rows.get(name);
      if (!row || row.type !== type) {
        row?.tr.remove();
        row = this._row(name, type);
        this.rows.set(name, row);
        this.observer.observe(row.tr);
      }
      this.els.body.insertBefore(row.tr, before);
      before = row.tr;
    }
    this.els.count.textContent = t('inspect.topics.count', { n: num(keep.size) });
    this.els.root.dataset.topics = String(keep.size);
  }

  _row(name, type) {
    const tr = document.createElement('tr');
    tr.dataset.topic = name;
    tr.tabIndex = 0;
    const cells = {};
    for (const key of ['name', 'type', 'pubs', 'subs', 'rate', 'bw']) {
      const td = document.createElement('td');
      td.className = key;
      cells[key] = td;
      tr.append(td);
    }
    cells.name.textContent = name;
    cells.type.textContent = type;
    cells.pubs.textContent = '·';
    cells.subs.textContent = '·';
    cells.rate.textContent = '·';
    cells.bw.textContent = '·';
    const choose = () => this.dispatchEvent(new CustomEvent('choose', { detail: { topic: name, type } }));
    tr.addEventListener('click', choose);
    tr.addEventListener('keydown', (e) => { if (e.key === 'Enter') choose(); });
    return { tr, type, cells, countedAt: 0 };
  }

  select(topic) {
    for (const [name, row] of this.rows) row.tr.toggleAttribute('aria-selected', name === topic);
  }

  // Rates and bandwidths of the rows in view; their publishers and subscribers now and then.
  async measure() {
    if (document.hidden || !this.wire.connected) return;
    const order = [...this.rows.keys()];   // the list's own order
    const topics = order.filter((n) => this.visible.has(n)).slice(0, 100);
    if (!topics.length) return;
    const now = performance.now();
    for (const name of topics) {
      const row = this.rows.get(name);
      if (now - row.countedAt < COUNTS_EVERY) continue;
      row.countedAt = now;
      this.wire.call('/rosapi/publishers', { topic: name }).then((r) => { row.cells.pubs.textContent = num(r.publishers.length); row.tr.dataset.pubs = String(r.publishers.length); }, () => {});
      this.wire.call('/rosapi/subscribers', { topic: name }).then((r) => { row.cells.subs.textContent = num(r.subscribers.length); }, () => {});
    }
    if (!this.stats) return;
    let r;
    try {
      r = await this.wire.call(STATS, { topics });
    } catch (e) {
      if (/does not exist|unknown|not available/i.test(e.message)) this.stats = false;   // another gateway
      return;
    }
    topics.forEach((name, i) => {
      const row = this.rows.get(name);
      if (!row) return;
      row.cells.rate.textContent = rate(r.rates[i]);
      row.cells.bw.textContent = bandwidth(r.bandwidths[i]);
      row.tr.dataset.rate = String(r.rates[i]);
    });
    this.dispatchEvent(new CustomEvent('measured', { detail: topics.map((name, i) => ({ topic: name, rate: r.rates[i], bandwidth: r.bandwidths[i] })) }));
  }
}
