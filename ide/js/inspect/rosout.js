// The /rosout log (rcl_interfaces/msg/Log, what every ROS 2 node's logger publishes): the newest
// KEEP lines, shown by level (at least the one chosen), node (the logger's name) and a search;
// it follows its newest line unless the reader has scrolled up.
import { t, time } from '../i18n.js';

export const LEVELS = { 10: 'debug', 20: 'info', 30: 'warn', 40: 'error', 50: 'fatal' };
const KEEP = 1000;

// The logger names of a robot namespace: '/s01' -> 's01.' (ROS names a node's logger 's01.turtlesim').
export const loggerPrefix = (ns) => (ns ? `${ns.replace(/^\//, '').replace(/\//g, '.')}.` : '');

export class RosoutLog {
  constructor(wire, els) {
    this.wire = wire;
    this.els = els;          // {root, list, level, node, search, count}
    this.lines = [];
    this.names = new Set();
    this.ns = '';
    this.sub = null;
    for (const el of [els.level, els.node]) el.addEventListener('change', () => this.render());
    els.search.addEventListener('input', () => this.render());
  }

  start() {
    this.sub?.close();
    this.sub = this.wire.subscribe('/rosout', 'rcl_interfaces/msg/Log', (m) => this.add(m), { queue_length: 100 },
      (why) => { this.els.count.textContent = t('inspect.refused', { why }); });
  }

  setNamespace(ns) { this.ns = ns; this.render(); }

  add(m) {
    this.lines.push(m);
    if (this.lines.length > KEEP) this.lines.shift();
    if (!this.names.has(m.name)) {
      this.names.add(m.name);
      const value = this.els.node.value;
      this.els.node.replaceChildren(new Option(t('inspect.log.all.nodes'), ''),
        ...[...this.names].sort().map((n) => new Option(n, n)));
      this.els.node.value = value;
    }
    if (this.matches(m)) this._append(m);
    this.els.root.dataset.lines = String(this.lines.length);
  }

  matches(m) {
    const text = this.els.search.value.trim().toLowerCase();
    const node = this.els.node.value;
    return m.level >= Number(this.els.level.value)
      && (!node || m.name === node)
      && (!this.ns || node || m.name.startsWith(loggerPrefix(this.ns)))
      && (!text || m.msg.toLowerCase().includes(text) || m.name.toLowerCase().includes(text));
  }

  _line(m) {
    const li = document.createElement('li');
    li.dataset.level = LEVELS[m.level] ?? String(m.level);
    li.dataset.node = m.name;
    const when = document.createElement('time');
    when.textContent = time((m.stamp?.sec ?? 0) * 1000 + (m.stamp?.nanosec ?? 0) / 1e6);
    const level = document.createElement('b');
    level.textContent = t(`inspect.level.${LEVELS[m.level] ?? 'info'}`);
    const name = document.createElement('span');
    name.className = 'node';
    name.textContent = m.name;
    const text = document.createElement('span');
    text.className = 'msg';
    text.textContent = m.msg;
    li.append(when, level, name, text);
    return li;
  }

  _append(m) {
    const list = this.els.list;
    const following = list.scrollTop + list.clientHeight >= list.scrollHeight - 4;
    list.append(this._line(m));
    while (list.children.length > KEEP) list.firstChild.remove();
    if (following) list.scrollTop = list.scrollHeight;
  }

  render() {
    const list = this.els.list;
    list.replaceChildren(...this.lines.filter((m) => this.matches(m)).map((m) => this._line(m)));
    list.scrollTop = list.scrollHeight;
  }
}
