// The graph between nodes and topics, drawn: nodes (boxes) and topics (rounded) in columns from
// the publishers on the left to the subscribers on the right (a layered drawing: each vertex one
// column right of what feeds it, cycles broken where a depth-first walk meets them; each column
// ordered by the mean row of its neighbours, a few sweeps). The SVG keeps its natural size in a
// scrolling box, so on a phone it is panned with a finger and read at its own size; zoom buttons
// scale it; a tap on a vertex lights its edges and neighbours. layout() is pure (for tests).
import { t } from '../i18n.js';

const SVG = 'http://www.w3.org/2000/svg';
const COL = 230, ROW = 44, BOX_H = 28, CHAR = 7.2, PAD = 12;
export const DEBUG_TOPICS = ['/rosout', '/parameter_events'];

// graph: {vertices: [{id, kind: 'node'|'topic', label}], edges: [[from, to]]} ->
// {positions: Map id -> {x, y, col, row}, width, height}
export function layout(graph) {
  const out = new Map(graph.vertices.map((v) => [v.id, []]));
  const inc = new Map(graph.vertices.map((v) => [v.id, []]));
  for (const [a, b] of graph.edges) { out.get(a)?.push(b); inc.get(b)?.push(a); }
  // back edges: met while their target is still open in a depth-first walk from the sources
  const state = new Map();
  const back = new Set();
  const starts = [...graph.vertices.filter((v) => !inc.get(v.id).length), ...graph.vertices].map((v) => v.id);
  for (const s of starts) {
    if (state.has(s)) continue;
    const stack = [[s, 0]];
    state.set(s, 'open');
    while (stack.length) {
      const top = stack[stack.length - 1];
      const next = out.get(top[0])[top[1]++];
      if (next === undefined) { state.set(top[0], 'done'); stack.pop(); continue; }
      if (state.get(next) === 'open') back.add(`${top[0]}\u0000${next}`);
      else if (!state.has(next)) { state.set(next, 'open'); stack.push([next, 0]); }
    }
  }
  const forward = graph.edges.filter(([a, b]) => !back.has(`${a}\u0000${b}`) && a !== b);
  // columns: the longest path from a source (over forward edges, in topological order)
  const col = new Map(graph.vertices.map((v) => [v.id, 0]));
  const indeg = new Map(graph.vertices.map((v) => [v.id, 0]));
  for (const [, b] of forward) indeg.set(b, indeg.get(b) + 1);
  const queue = graph.vertices.filter((v) => !indeg.get(v.id)).map((v) => v.id);
  const fwdOut = new Map(graph.vertices.map((v) => [v.id, []]));
  for (const [a, b] of forward) fwdOut.get(a).push(b);
  while (queue.length) {
    const v = queue.shift();
    for (const w of fwdOut.get(v)) {
      col.set(w, Math.max(col.get(w), col.get(v) + 1));
      indeg.set(w, indeg.get(w) - 1);
      if (!indeg.get(w)) queue.push(w);
    }
  }
  const columns = [];
  for (const v of graph.vertices) (columns[col.get(v.id)] ??= []).push(v.id);
  const row = new Map();
  const place = () => columns.forEach((c) => c?.forEach((id, i) => row.set(id, i)));
  place();
  const mean = (ids) => (ids.length ? ids.reduce((s, id) => s + row.get(id), 0) / ids.length : null);
  for (let sweep = 0; sweep < 4; sweep += 1) {
    const order = sweep % 2 ? [...columns].reverse() : columns;
    for (const c of order) {
      if (!c) continue;
      const key = new Map(c.map((id) => [id, mean(sweep % 2 ? out.get(id) : inc.get(id)) ?? row.get(id)]));
      c.sort((a, b) => key.get(a) - key.get(b));
      c.forEach((id, i) => row.set(id, i));
    }
  }
  const positions = new Map();
  let rows = 0;
  columns.forEach((c, i) => c?.forEach((id, r) => { positions.set(id, { x: PAD + i * COL, y: PAD + r * ROW, col: i, row: r }); rows = Math.max(rows, r + 1); }));
  return { positions, width: PAD * 2 + Math.max(1, columns.length) * COL, height: PAD * 2 + Math.max(1, rows) * ROW };
}

const el = (tag, attrs = {}) => {
  const e = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  return e;
};

export class GraphView {
  constructor(wire, els) {
    this.wire = wire;
    this.els = els;       // {root, box, debug, zoomIn, zoomOut, info}
    this.scale = 1;
    this.ns = '';
    this.graph = null;
    els.zoomIn.addEventListener('click', () => this.zoom(1.25));
    els.zoomOut.addEventListener('click', () => this.zoom(0.8));
    els.debug.addEventListener('change', () => this.refresh());
  }

  setNamespace(ns) { this.ns = ns; }

  zoom(f) {
    this.scale = Math.min(3, Math.max(0.3, this.scale * f));
    const svg = this.els.box.querySelector('svg');
    if (svg) { svg.style.width = `${svg.viewBox.baseVal.width * this.scale}px`; svg.style.height = `${svg.viewBox.baseVal.height * this.scale}px`; }
  }

  // Reads every node's details (in the namespace) and draws them.
  async refresh() {
    let nodes;
    try { nodes = (await this.wire.call('/rosapi/nodes')).nodes; } catch { return; }
    nodes = nodes.filter((n) => !this.ns || n.startsWith(`${this.ns}/`));
    const details = await Promise.all(nodes.map((n) => this.wire.call('/rosapi/node_details', { node: n }).catch(() => null)));
    const hide = new Set(this.els.debug.checked ? [] : DEBUG_TOPICS);
    const vertices = [], edges = [], topics = new Set();
    nodes.forEach((n, i) => {
      if (!details[i]) return;
      vertices.push({ id: `n:${n}`, kind: 'node', label: n });
      for (const topic of details[i].publishing) if (!hide.has(topic)) { topics.add(topic); edges.push([`n:${n}`, `t:${topic}`]); }
      for (const topic of details[i].subscribing) if (!hide.has(topic)) { topics.add(topic); edges.push([`t:${topic}`, `n:${n}`]); }
    });
    for (const topic of [...topics].sort()) vertices.push({ id: `t:${topic}`, kind: 'topic', label: topic });
    this.graph = { vertices, edges };
    this.draw();
  }

  draw() {
    const { vertices, edges } = this.graph;
    const { positions, width, height } = layout(this.graph);
    const svg = el('svg', { viewBox: `0 0 ${width} ${height}`, role: 'img', 'aria-label': t('inspect.graph.label') });
    svg.style.width = `${width * this.scale}px`;
    svg.style.height = `${height * this.scale}px`;
    const defs = el('defs');
    const marker = el('marker', { id: 'arrow', viewBox: '0 0 10 10', refX: 9, refY: 5, markerWidth: 7, markerHeight: 7, orient: 'auto-start-reverse' });
    marker.append(el('path', { d: 'M0 0 L10 5 L0 10 z', class: 'arrowhead' }));
    defs.append(marker);
    svg.append(defs);
    const widthOf = (v) => Math.min(COL - 30, v.label.length * CHAR + 16);
    const byId = new Map(vertices.map((v) => [v.id, v]));
    const lines = el('g', { class: 'edges' });
    const boxes = el('g', { class: 'vertices' });
    const drawn = new Map();
    for (const [a, b] of edges) {
      const p = positions.get(a), q = positions.get(b);
      const x1 = p.x + widthOf(byId.get(a)), y1 = p.y + BOX_H / 2, x2 = q.x, y2 = q.y + BOX_H / 2;
      const bend = Math.max(40, Math.abs(x2 - x1) / 2);
      const path = el('path', { d: `M${x1} ${y1} C${x1 + bend} ${y1} ${x2 - bend} ${y2} ${x2} ${y2}`, 'marker-end': 'url(#arrow)', class: 'edge' });
      path.dataset.from = a;
      path.dataset.to = b;
      lines.append(path);
    }
    for (const v of vertices) {
      const p = positions.get(v.id);
      const g = el('g', { class: `vertex ${v.kind}`, transform: `translate(${p.x} ${p.y})`, tabindex: 0 });
      g.dataset.id = v.id;
      const w = widthOf(v);
      g.append(el('rect', { width: w, height: BOX_H, rx: v.kind === 'topic' ? BOX_H / 2 : 4 }));
      const text = el('text', { x: w / 2, y: BOX_H / 2 + 4, 'text-anchor': 'middle' });
      text.textContent = v.label.length * CHAR + 16 > w ? `…${v.label.slice(-Math.floor((w - 16) / CHAR) + 1)}` : v.label;
      const title = el('title');
      title.textContent = v.label;
      g.append(text, title);
      g.addEventListener('click', () => this.light(v.id));
      boxes.append(g);
      drawn.set(v.id, g);
    }
    svg.append(lines, boxes);
    this.els.box.replaceChildren(svg);
    this.els.root.dataset.vertices = String(vertices.length);
    this.els.root.dataset.edges = String(edges.length);
    this.els.info.textContent = t('inspect.graph.info', { nodes: vertices.filter((v) => v.kind === 'node').length, topics: vertices.filter((v) => v.kind === 'topic').length });
  }

  // Lights a vertex's edges and neighbours (a second tap: all again).
  light(id) {
    const svg = this.els.box.querySelector('svg');
    const same = svg.dataset.lit === id;
    svg.dataset.lit = same ? '' : id;
    const near = new Set([id]);
    for (const p of svg.querySelectorAll('.edge')) {
      const on = !same && (p.dataset.from === id || p.dataset.to === id);
      p.classList.toggle('lit', on);
      if (on) { near.add(p.dataset.from); near.add(p.dataset.to); }
    }
    for (const g of svg.querySelectorAll('.vertex')) g.classList.toggle('dim', !same && !near.has(g.dataset.id));
  }
}
