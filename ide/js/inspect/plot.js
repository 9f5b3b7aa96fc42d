// A plot of any numeric fields of any topics (uPlot, as the teleop page's history): each series a
// (topic, field path) pair, each topic subscribed once (at most RATE messages a second), the rows
// of the last `span` seconds kept (at most MAX_ROWS); Pause stops taking messages (and the
// subscriptions), CSV gives the rows, PNG the chart. The fields offered are a topic's numeric
// leaves (tree.js), read off its first message.
import uPlot from 'uplot';
import { field } from '../../runtime/util.js';
import { leaves } from './tree.js';
import { t, num } from '../i18n.js';
import { download } from '../views/download.js';

const COLOURS = ['#ff7043', '#42a5f5', '#66bb6a', '#ab47bc', '#ffca28', '#26c6da', '#ef5350', '#8d6e63'];
const MAX_ROWS = 20000;
const THROTTLE = 20;   // ms: at most 50 messages a second per topic

export function csv(series, rows) {
  const quote = (v) => (/[",\n]/.test(v) ? `"${v.replaceAll('"', '""')}"` : v);
  const head = ['time', 'unix', ...series.map((s) => `${s.topic} ${s.path}`)].map(quote).join(',');
  const lines = rows.t.map((tm, i) => [new Date(tm * 1000).toISOString(), String(tm),
    ...series.map((s, j) => (rows.v[j][i] === null || rows.v[j][i] === undefined ? '' : String(rows.v[j][i])))].join(','));
  return `${[head, ...lines].join('\n')}\n`;
}


export class Plot {
  constructor(wire, els) {
    this.wire = wire;
    this.els = els;   // {root, chart, topic, field, add, pause, clear, span, csv, png, legend, info}
    this.series = [];            // {topic, path, colour}
    this.rows = { t: [], v: [] };
    this.subs = new Map();       // topic -> subscription
    this.paused = false;
    this.chart = null;
    this.types = new Map();
    this.drawQueued = false;
    els.topic.addEventListener('change', () => this.offerFields(els.topic.value.trim()));
    els.add.addEventListener('click', () => this.add(els.topic.value.trim(), els.field.value.trim()));
    els.pause.addEventListener('click', () => this.pause(!this.paused));
    els.clear.addEventListener('click', () => { this.rows = { t: [], v: this.series.map(() => []) }; this.draw(); });
    els.span.addEventListener('change', () => this.draw());
    els.csv.addEventListener('click', () => download('plot.csv', csv(this.series, this.rows), 'text/csv'));
    els.png.addEventListener('click', () => {
      const canvas = this.els.chart.querySelector('canvas');
      if (canvas) canvas.toBlob((b) => download('plot.png', b), 'image/png');
    });
    new ResizeObserver(() => this.chart?.setSize(this.size())).observe(els.chart);
  }

  setTopics(types) { this.types = types; }

  // The numeric fields of a topic's first message, offered in the field menu.
  offerFields(topic) {
    if (topic === this.offered) return;   // (the field's change on leaving it: the same topic)
    this.offered = topic;
    this.els.field.replaceChildren();
    if (!topic) return;
    this.els.info.textContent = t('inspect.plot.reading', { topic });
    this.offering?.close();
    const sub = this.wire.subscribe(topic, this.types.get(topic), (msg) => {
      if (this.offering !== sub) return;   // a second message already on its way
      this.offering = null;
      sub.close();
      const paths = leaves(msg).map(([p]) => p);
      this.els.field.replaceChildren(...paths.map((p) => new Option(p, p)));
      this.els.info.textContent = paths.length ? '' : t('inspect.plot.no.numbers', { topic });
      this.els.root.dataset.fields = String(paths.length);
    }, { queue_length: 1 }, (why) => { this.els.info.textContent = t('inspect.refused', { why }); });
    this.offering = sub;
  }

  add(topic, path) {
    if (!topic || !path || this.series.some((s) => s.topic === topic && s.path === path)) return;
    this.series.push({ topic, path, colour: COLOURS[this.series.length % COLOURS.length] });
    this.rows.v.push(this.rows.t.map(() => null));
    this._subscribe(topic);
    this.build();
  }

  remove(i) {
    const [gone] = this.series.splice(i, 1);
    this.rows.v.splice(i, 1);
    if (!this.series.some((s) => s.topic === gone.topic)) { this.subs.get(gone.topic)?.close(); this.subs.delete(gone.topic); }
    this.build();
  }

  pause(on) {
    this.paused = on;
    this.els.pause.setAttribute('aria-pressed', String(on));
    this.els.pause.textContent = t(on ? 'inspect.echo.resume' : 'inspect.echo.pause');
    this.els.root.dataset.paused = String(on);
    if (on) { for (const s of this.subs.values()) s.close(); this.subs.clear(); } else {
      for (const topic of new Set(this.series.map((s) => s.topic))) this._subscribe(topic);
    }
  }

  _subscribe(topic) {
    if (this.subs.has(topic) || this.paused) return;
    this.subs.set(topic, this.wire.subscribe(topic, this.types.get(topic), (msg) => this._message(topic, msg),
      { throttle_rate: THROTTLE, queue_length: 1 }, (why) => { this.els.info.textContent = t('inspect.refused', { why }); }));
  }

  _message(topic, msg) {
    if (this.paused) return;
    const now = Date.now() / 1000;
    this.rows.t.push(now);
    this.series.forEach((s, j) => {
      let v = null;
      if (s.topic === topic) { try { v = Number(field(msg, s.path)); } catch { v = null; } }
      this.rows.v[j].push(Number.isFinite(v) ? v : null);
    });
    if (this.rows.t.length > MAX_ROWS) { this.rows.t.shift(); for (const col of this.rows.v) col.shift(); }
    this.els.root.dataset.rows = String(this.rows.t.length);
    if (!this.drawQueued) {
      this.drawQueued = true;
      requestAnimationFrame(() => { this.drawQueued = false; this.draw(); });
    }
  }

  size() { return { width: Math.max(240, this.els.chart.clientWidth), height: 220 }; }

  build() {
    this.chart?.destroy();
    this.chart = null;
    this.els.legend.replaceChildren(...this.series.map((s, i) => {
      const li = document.createElement('li');
      li.style.setProperty('--c', s.colour);
      li.textContent = `${s.topic} ${s.path} `;
      const x = document.createElement('button');
      x.type = 'button';
      x.textContent = '×';
      x.setAttribute('aria-label', t('inspect.plot.remove'));
      x.addEventListener('click', () => this.remove(i));
      li.append(x);
      return li;
    }));
    this.els.root.dataset.series = String(this.series.length);
    if (!this.series.length) { this.els.chart.replaceChildren(); return; }
    this.chart = new uPlot({
      ...this.size(),
      legend: { show: false },
      scales: { x: { time: true, range: () => { const now = Date.now() / 1000; return [now - Number(this.els.span.value), now]; } } },
      axes: [{ stroke: '#aab3cc', grid: { stroke: '#2c3350' } }, { stroke: '#aab3cc', grid: { stroke: '#2c3350' }, size: 60 }],
      series: [{}, ...this.series.map((s) => ({ label: `${s.topic} ${s.path}`, stroke: s.colour, width: 2, spanGaps: true }))],
    }, this.data(), this.els.chart);
  }

  data() {
    const from = Date.now() / 1000 - Number(this.els.span.value);
    let i = 0;
    while (i < this.rows.t.length && this.rows.t[i] < from) i += 1;
    return [this.rows.t.slice(i), ...this.rows.v.map((col) => col.slice(i))];
  }

  draw() {
    if (!this.chart) return;
    this.chart.setData(this.data());
    const last = this.series.map((s, j) => this.rows.v[j].findLast((v) => v !== null));
    this.els.info.textContent = this.series.length ? t('inspect.plot.rows', { n: num(this.rows.t.length), last: last.map((v) => num(v ?? NaN, 3)).join(' · ') }) : '';
  }
}
