// The teleop page's dashboard, as robot apps have it: gauges with warning colours (battery,
// motor temperatures) and history plots, one chart per unit with its own axis. The history of
// the plotted fields is kept for ten minutes in this browser, per robot namespace, so a reload
// keeps it; longer spans come from the gateway's history (history.js) through replace().
import uPlot from 'uplot';
import { num } from '../i18n.js';

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
    this.fixed = null;         // [from, to] of a span chosen by its dates: no live samples join it
    this.zoom = null;          // [from, to] of a drag or a pinch, over whatever the span
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
    if (this.fixed) return;   // a span of the past is not this browser's own recent history
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
      cursor: { drag: { x: true, y: false, setScale: false } },
      hooks: { setSelect: [(u) => this.selected(u)] },
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
    c.div.ondblclick = () => this.setZoom(null);
    this.legend(c);
  }

  // A drag across a chart: every chart shows that span (a double-click shows the whole again)
  selected(u) {
    const { left, width } = u.select;
    if (width < 3) return;
    u.setSelect({ left: 0, top: 0, width: 0, height: 0 }, false);
    this.setZoom([u.posToVal(left, 'x'), u.posToVal(left + width, 'x')]);
  }

  setZoom(range) {
    this.zoom = range && range[1] > range[0] ? range : null;
    this.el.dataset.zoom = this.zoom ? this.zoom.map((v) => v.toFixed(3)).join(' ') : '';
    for (const c of this.charts.values()) this.draw(c);
  }

  // Two fingers apart or together on a chart: the span shown narrows or widens around them
  bindPinch() {
    let start = null;
    const apart = (e) => Math.abs(e.touches[0].clientX - e.touches[1].clientX) || 1;
    this.el.addEventListener('touchstart', (e) => {
      if (e.touches.length !== 2) { start = null; return; }
      const [lo, hi] = this.span();
      const box = this.el.getBoundingClientRect();
      const mid = ((e.touches[0].clientX + e.touches[1].clientX) / 2 - box.left) / box.width;
      start = { d: apart(e), lo, hi, at: lo + (hi - lo) * Math.max(0, Math.min(1, mid)) };
    }, { passive: true });
    this.el.addEventListener('touchmove', (e) => {
      if (!start || e.touches.length !== 2) return;
      e.preventDefault();
      const f = start.d / apart(e);   // fingers apart: a shorter span
      this.setZoom([start.at - (start.at - start.lo) * f, start.at + (start.hi - start.at) * f]);
    }, { passive: false });
    this.el.addEventListener('touchend', () => { start = null; });
  }

  /** The rows of the span shown as CSV: UTC time, seconds since 1970, then a column per series. */
  csv() {
    const [lo, hi] = this.span();
    const cols = this.series.filter((s) => this.rows[s.id]);
    const head = ['time', 'unix', ...cols.map((s) => (s.unit ? `${s.label} (${s.unit})` : s.label))];
    const quote = (v) => (/[",\n]/.test(v) ? `"${v.replaceAll('"', '""')}"` : v);
    const lines = [head.map(quote).join(',')];
    this.rows.t.forEach((t, i) => {
      if (t < lo || t > hi) return;
      lines.push([new Date(t * 1000).toISOString(), String(t), ...cols.map((s) => {
        const v = this.rows[s.id][i];
        return v === null || v === undefined ? '' : String(v);
      })].join(','));
    });
    return `${lines.join('\n')}\n`;
  }

  /** The charts as one PNG (a Blob): each chart's canvas with its axes, and its legend under it. */
  png() {
    const scale = devicePixelRatio || 1;
    const parts = [...this.charts.values()].map((c) => ({ canvas: c.div.querySelector('canvas'), legend: c.readout.textContent ? [...c.readout.children] : [] }));
    const width = Math.max(...parts.map((p) => p.canvas.width));
    const line = 16 * scale;
    const height = parts.reduce((h, p) => h + p.canvas.height + line * (p.legend.length + 0.5), 0);
    const out = document.createElement('canvas');
    out.width = width;
    out.height = Math.ceil(height);
    const g = out.getContext('2d');
    g.fillStyle = '#1b2030';
    g.fillRect(0, 0, out.width, out.height);
    g.font = `${12 * scale}px system-ui, sans-serif`;
    let y = 0;
    for (const p of parts) {
      g.drawImage(p.canvas, 0, y);
      y += p.canvas.height;
      for (const span of p.legend) {
        y += line;
        g.fillStyle = span.style.getPropertyValue('--c') || '#aab3cc';
        g.fillRect(8 * scale, y - 7 * scale, 10 * scale, 3 * scale);
        g.fillStyle = '#e9ecf5';
        g.fillText(span.textContent, 24 * scale, y - 2 * scale);
      }
      y += line / 2;
    }
    return new Promise((resolve) => out.toBlob(resolve, 'image/png'));
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
    if (this.zoom) return this.zoom;
    if (this.fixed) return this.fixed;
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
    if (this.fixed) return;   // a span of the past: it stays as the gateway gave it
    this.rows.t.push(now);
    for (const s of this.series) this.rows[s.id].push(Number.isFinite(s.last) ? s.last : null);
    for (const k of Object.keys(this.rows)) {   // series no longer shown stay aligned
      if (this.rows[k].length < this.rows.t.length) this.rows[k].push(null);
    }
    this.trim(this.rows, now);
    for (const c of this.charts.values()) this.draw(c);
  }

  // Rows from elsewhere (the gateway's history over `window` seconds); live samples follow them.
  // A live span keeps the page's own samples newer than the gateway's last row: the gateway writes
  // its points every few seconds, so what the page just showed may not be there yet.
  replace(rows, window, fixed = null) {
    this.window = window;
    const live = !fixed && !this.fixed;
    this.fixed = fixed;
    this.zoom = null;
    this.el.dataset.zoom = '';
    for (const k of Object.keys(this.rows)) if (!rows[k] && !/:(min|max)$/.test(k)) rows[k] = rows.t.map(() => null);
    if (live) {
      const last = rows.t.length ? rows.t[rows.t.length - 1] : -Infinity;
      this.rows.t.forEach((t, i) => {
        if (t <= last) return;
        rows.t.push(t);
        for (const k of Object.keys(rows)) if (k !== 't') rows[k].push(this.rows[k]?.[i] ?? null);
      });
    }
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
