// The teleop page's dashboard, as robot apps have it: gauges with warning colours (battery,
// motor temperatures) and history plots, one chart per unit with its own axis. The history of
// the plotted fields is kept for ten minutes in this browser, per robot namespace, so a reload
// keeps it; longer spans come from the gateway's history (history.js) through replace().
import uPlot from 'uplot';
import { num } from './i18n.js';

export const WINDOW = 600;         // s of history kept
export const SAMPLE_EVERY = 1000;  // ms between history rows
const ARC = Math.PI * 48;          // length of the gauge's half circle
const COLOURS = ['#ff7043', '#42a5f5', '#66bb6a', '#ab47bc', '#ffca28', '#26c6da'];
const SVG = 'http://www.w3.org/2000/svg';

const svg = (tag, attrs) => {
  const el = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
  return el;
};

/**
 * A half-circle gauge in el. Levels: 'ok', 'warn', 'danger' (el.dataset.level), by `warn` and
 * `danger` thresholds, rising (temperatures) or falling (`low: true`, a battery).
 */
export function gauge(el, { label, unit, min, max, warn, danger, low = false, digits = 0, auto = false }) {
  const path = 'M12 60 A48 48 0 0 1 108 60';
  const back = svg('path', { d: path, class: 'g-back' });
  const fill = svg('path', { d: path, class: 'g-fill', 'stroke-dasharray': `0 ${ARC}` });
  const text = svg('text', { x: 60, y: 56, class: 'g-value', 'text-anchor': 'middle' });
  const name = svg('text', { x: 60, y: 76, class: 'g-label', 'text-anchor': 'middle' });
  name.textContent = label;
  text.textContent = '–';
  const box = svg('svg', { viewBox: '0 0 120 80', role: 'img', 'aria-label': label });
  box.append(back, fill, text, name);
  el.classList.add('gauge');
  el.replaceChildren(box);
  el.dataset.level = '';
  return {
    // level: the robot's own word over the thresholds (a battery's health, its charging)
    set(v, level = null) {
      if (!Number.isFinite(v)) { text.textContent = '?'; el.dataset.level = ''; return; }
      if (auto && Math.abs(v) > max) max = Math.abs(v) * 1.25;   // a scale with no limit given: the largest seen
      const f = Math.max(0, Math.min(1, (v - min) / (max - min)));
      fill.setAttribute('stroke-dasharray', `${f * ARC} ${ARC}`);
      text.textContent = `${num(v, digits)}${unit}`;
      el.dataset.level = level ?? ((low ? v <= danger : v >= danger) ? 'danger' : (low ? v <= warn : v >= warn) ? 'warn' : 'ok');
      el.dataset.value = String(v);
      box.setAttribute('aria-label', `${label} ${text.textContent}`);
    },
  };
}

/**
 * History plots: series grouped into charts by unit; add(series) then sample() once a second.
 * series: {id, label, unit, last} (last: the latest value, set by whoever receives it).
 */
export class History {
  constructor(el, key) {
    this.el = el;
    this.key = key;
    this.series = [];
    this.charts = new Map();   // unit -> {div, readout, chart, series: [...]}
    this.window = WINDOW;      // s of rows kept (a longer span chosen: as long as that)
    this.rows = this.load();   // {t: [...], [id]: [...]}
  }

  load() {
    try {
      const rows = JSON.parse(localStorage.getItem(this.key));
      if (rows && Array.isArray(rows.t)) return this.trim(rows);
    } catch { /* nothing kept, or storage off */ }
    return { t: [] };
  }

  save() {
    try { localStorage.setItem(this.key, JSON.stringify(this.rows)); } catch { /* storage full or off */ }
  }

  trim(rows, now = Date.now() / 1000) {
    let drop = 0;
    while (drop < rows.t.length && rows.t[drop] < now - (this.window ?? WINDOW)) drop += 1;
    if (drop) for (const k of Object.keys(rows)) rows[k] = rows[k].slice(drop);
    return rows;
  }

  add(s) {
    this.series.push(s);
    if (!this.rows[s.id]) this.rows[s.id] = this.rows.t.map(() => null);
    const unit = s.unit ?? '';
    if (!this.charts.has(unit)) {
      const div = document.createElement('div');
      div.className = 'chart';
      div.dataset.unit = unit;
      const readout = document.createElement('p');
      readout.className = 'readout legend';
      this.el.append(div, readout);
      this.charts.set(unit, { div, readout, chart: null, series: [] });
    }
    const c = this.charts.get(unit);
    c.series.push(s);
    this.build(c);
  }

  build(c) {
    c.chart?.destroy();
    const unit = c.div.dataset.unit;
    const banded = this.banded(c);
    c.chart = new uPlot({
      width: Math.max(220, this.el.clientWidth),
      height: 110,
      legend: { show: false },
      cursor: { drag: { x: false, y: false } },
      scales: { x: { time: true, range: () => this.span() },
      y: unit === '%' ? { range: [0, 100] } : {} },
      axes: [
        { stroke: '#aab3cc', grid: { stroke: '#2c3350' }, size: 28 },
        { stroke: '#aab3cc', grid: { stroke: '#2c3350' }, size: 58, label: unit, labelSize: 16, labelGap: 0 },
      ],
      series: [{}, ...c.series.map((s) => ({
        label: s.label, stroke: this.colour(s), width: 2, spanGaps: true })),
      ...banded.flatMap((s) => [`${s.id}:max`, `${s.id}:min`].map((label) => ({
        label, stroke: 'transparent', width: 0, points: { show: false }, spanGaps: true })))],
      bands: banded.map((s, i) => ({
        series: [1 + c.series.length + 2 * i, 2 + c.series.length + 2 * i], fill: `${this.colour(s)}33` })),
    }, this.data(c), c.div);
    c.bands = banded.map((s) => s.id).join(' ');
    this.legend(c);
  }

  data(c) {
    return [this.rows.t, ...c.series.map((s) => this.rows[s.id]),
      ...this.banded(c).flatMap((s) => [this.rows[`${s.id}:max`], this.rows[`${s.id}:min`]])];
  }

  colour(s) { return COLOURS[this.series.indexOf(s) % COLOURS.length]; }

  // The chart's series with a min and a max per row (a span the gateway gave in steps): a band.
  banded(c) { return c.series.filter((s) => this.rows[`${s.id}:min`] && this.rows[`${s.id}:max`]); }

  // The time shown: the samples' own, and at least the last minute (uPlot alone would widen one
  // sample to a thousand days).
  span() {
    const t = this.rows.t;
    const hi = t.length ? t[t.length - 1] : Date.now() / 1000;
    return [Math.min(t.length ? t[0] : hi, hi - 60), hi];
  }

  draw(c) {
    c.chart.setData(this.data(c));
    const [min, max] = this.span();
    c.chart.setScale('x', { min, max });
    this.legend(c);
  }

  // The latest values beside each series' name (not the cursor's: no "--" while nobody hovers).
  legend(c) {
    c.readout.replaceChildren(...c.series.map((s) => {
      const span = document.createElement('span');
      span.style.setProperty('--c', this.colour(s));
      span.dataset.id = s.id;
      const v = s.last ?? this.rows[s.id].findLast((x) => x !== null);
      span.textContent = `${s.label} ${num(v, 2)}${c.div.dataset.unit ? ` ${c.div.dataset.unit}` : ''}`;
      return span;
    }));
  }

  sample(now = Date.now() / 1000) {
    this.rows.t.push(now);
    for (const s of this.series) this.rows[s.id].push(Number.isFinite(s.last) ? s.last : null);
    for (const k of Object.keys(this.rows)) {   // series no longer shown stay aligned
      if (this.rows[k].length < this.rows.t.length) this.rows[k].push(null);
    }
    this.trim(this.rows, now);
    for (const c of this.charts.values()) this.draw(c);
  }

  // Rows from elsewhere (the gateway's history over `window` seconds); live samples follow them.
  replace(rows, window) {
    this.window = window;
    for (const k of Object.keys(this.rows)) if (!rows[k] && !/:(min|max)$/.test(k)) rows[k] = rows.t.map(() => null);
    this.rows = rows;
    for (const c of this.charts.values()) {
      if (c.bands === this.banded(c).map((s) => s.id).join(' ')) this.draw(c);
      else { this.build(c); this.draw(c); }   // bands came or went with the span
    }
  }

  resize() {
    for (const c of this.charts.values()) c.chart?.setSize({ width: Math.max(220, this.el.clientWidth), height: 110 });
  }
}
