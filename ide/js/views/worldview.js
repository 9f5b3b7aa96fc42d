// Draws /world/markers (visualization_msgs/MarkerArray) from above, like a 2-D RViz:
// bounds, walls, pen trails, laser hits and robots. Works for any robot that publishes it.
// Markers in different frames are different worlds (turtlesim's square and the rover's arena):
// one is drawn at a time, scaled to fill the canvas, with tabs to choose when there are several;
// a tap on the view enlarges it (a tap or Escape brings it back). The robot's map
// (nav_msgs/OccupancyGrid, ``map`` beside ``world/markers``, made to measure: grid.js) lies under
// the markers of its frame, or alone when there are none.
import { yaw } from '../../runtime/util.js';
import { gridImage, mapSubscribe } from './grid.js';
import { publishedOf } from '../robot/graph.js';
import { t } from '../i18n.js';

const ARROW = 0, CUBE = 1, SPHERE = 2, CYLINDER = 3, LINE_STRIP = 4, LINE_LIST = 5,
  CUBE_LIST = 6, SPHERE_LIST = 7, POINTS = 8, TEXT = 9;
const DELETE = 2, DELETEALL = 3;
const FLOOR = '#c7c2b8';   // an outline-only world gets a neutral floor
const LAYER = { bounds: 0, walls: 1, pen: 2, scan: 3, robots: 5 };
const KEY = 'rosgate.world';
const PAD = 8;

const rgba = (c, fallback = 'rgba(200,200,200,1)') => (c
  ? `rgba(${Math.round(c.r * 255)},${Math.round(c.g * 255)},${Math.round(c.b * 255)},${c.a === 0 ? 1 : c.a ?? 1})`
  : fallback);
const frameOf = (m) => m.header?.frame_id || 'world';

export class WorldView {
  // stream: options of its subscribe (throttle_rate, queue_length), 10 Hz and 20 queued by default
  constructor(canvas, topic = '/world/markers', { tabs = true, enlarge = true, stream = {} } = {}) {
    this.canvas = canvas;
    this.stream = { queue_length: 20, ...stream };
    this.topic = topic;
    this.markers = new Map();   // 'ns/id' -> marker
    this.dirty = true;
    this.count = 0;             // MarkerArrays received
    this.ros = null;
    this.subscribed = new Set();   // the topics subscribed on this connection
    this.frame = null;          // the chosen world (a frame id); null: the remembered or first one
    try { this.frame = localStorage.getItem(KEY); } catch { /* storage off */ }
    this.big = null;            // the enlarged view's canvas while it is open
    this.fit = null;            // {w, h, scale, extent} of the last drawing, for tests
    this.listener = (m) => this.receive(m.msg);
    this.grid = null;           // the map's image and where it lies (grid.js)
    this.mapListener = (m) => { this.grid = gridImage(m.msg); this.dirty = true; };
    if (tabs) this._makeTabs();
    if (enlarge) canvas.addEventListener('click', () => this.enlarge(true));
    new ResizeObserver(() => { this.dirty = true; }).observe(canvas);
    const loop = () => {
      if (this.dirty) { this.dirty = false; this.draw(); if (this.big) this.draw(this.big); this._showTabs(); }
      requestAnimationFrame(loop);
    };
    requestAnimationFrame(loop);
  }

  // The connection to draw from. Nothing is subscribed until look() has seen a topic published:
  // a subscription to a topic the robot does not have would make it appear on the graph.
  attach(ros) {
    if (this.ros) { this.ros.off(this.topic, this.listener); this.ros.off(this.mapTopic, this.mapListener); }
    this.ros = ros;
    this.subscribed = new Set();
    this.markers.clear();
    this.dirty = true;
  }

  get mapTopic() { return this.topic.replace(/world\/markers$/, 'map'); }

  // Subscribes to the markers and the map where something publishes them (call: a rosapi call,
  // for /rosapi/publishers); a topic already subscribed is not asked about again.
  async look(call) {
    const ros = this.ros;
    if (!ros?.isConnected) return;
    const wanted = [this.topic, this.mapTopic].filter((t) => !this.subscribed.has(t));
    if (!wanted.length) return;
    const topic = this.topic;
    const present = await publishedOf(call, wanted);
    if (this.ros !== ros || this.topic !== topic) return;   // another connection, or another topic, since
    if (present.has(this.topic) && !this.subscribed.has(this.topic)) {
      this.subscribed.add(this.topic);
      ros.on(this.topic, this.listener);
      ros.callOnConnection({
        op: 'subscribe', id: `subscribe:${this.topic}:worldview`, topic: this.topic,
        type: 'visualization_msgs/msg/MarkerArray', ...this.stream,
      });
    }
    if (present.has(this.mapTopic) && !this.subscribed.has(this.mapTopic)) {
      this.subscribed.add(this.mapTopic);
      ros.on(this.mapTopic, this.mapListener);
      ros.callOnConnection(mapSubscribe(this.mapTopic, `subscribe:${this.mapTopic}:worldview`));
    }
  }

  // Draws another topic (the world of another robot namespace); look() subscribes it.
  setTopic(topic) {
    if (topic === this.topic) return;
    const ros = this.ros;
    if (ros) {
      ros.off(this.topic, this.listener);
      ros.off(this.mapTopic, this.mapListener);
      for (const t of this.subscribed ?? []) ros.callOnConnection({ op: 'unsubscribe', id: `subscribe:${t}:worldview`, topic: t });
    }
    this.grid = null;
    this.topic = topic;
    this.subscribed = new Set();
    this.markers.clear();
    this.dirty = true;
    if (ros?.isConnected) this.attach(ros);
  }

  // The worlds (frames) markers came in, each with the names of the robots in it.
  worlds() {
    const out = new Map();
    for (const m of this.markers.values()) {
      const f = frameOf(m);
      if (!out.has(f)) out.set(f, []);
      if (m.ns === 'robots' && m.text) out.get(f).push(m.text);
    }
    return [...out].map(([frame, robots]) => ({ frame, robots: robots.sort() }))
      .sort((a, b) => a.frame.localeCompare(b.frame));
  }

  // The world drawn: the chosen one when it exists, else 'world', else the first.
  current() {
    const frames = this.worlds().map((w) => w.frame);
    if (frames.includes(this.frame)) return this.frame;
    return frames.includes('world') ? 'world' : frames[0] ?? 'world';
  }

  choose(frame) {
    this.frame = frame;
    try { localStorage.setItem(KEY, frame); } catch { /* storage off */ }
    this.dirty = true;
  }

  visible() {
    const f = this.current();
    return [...this.markers.values()].filter((m) => frameOf(m) === f);
  }

  _makeTabs() {
    const bar = document.createElement('div');
    bar.className = 'world-tabs';
    bar.setAttribute('role', 'tablist');
    bar.style.cssText = 'display:none;gap:4px;padding:4px;background:#1d2230;flex-wrap:wrap';
    this.canvas.before(bar);
    this.tabs = bar;
  }

  _showTabs() {
    const bar = this.tabs;
    if (!bar) return;
    const worlds = this.worlds();
    const current = this.current();
    const key = worlds.map((w) => `${w.frame}:${w.robots.join('+')}`).join(',') + `|${current}`;
    if (bar.dataset.key === key) return;
    bar.dataset.key = key;
    bar.style.display = worlds.length > 1 ? 'flex' : 'none';
    bar.replaceChildren(...worlds.map((w) => {
      const b = document.createElement('button');
      b.type = 'button';
      b.dataset.frame = w.frame;
      b.setAttribute('role', 'tab');
      b.setAttribute('aria-selected', String(w.frame === current));
      b.textContent = w.robots.length ? w.robots.join(', ') : w.frame;
      b.title = t('world.tab.title', { frame: w.frame });
      b.style.cssText = `font:inherit;font-size:12px;min-height:28px;padding:2px 10px;border-radius:6px;cursor:pointer;
        border:1px solid #3b4460;color:#e9ecf5;background:${w.frame === current ? '#3f6fd8' : '#2e3650'}`;
      b.onclick = () => this.choose(w.frame);
      return b;
    }));
  }

  // Opens (or closes) the enlarged view over the page.
  enlarge(open = !this.big) {
    if (!open) {
      this.big?.closest('.world-big')?.remove();
      this.big = null;
      return;
    }
    if (this.big) return;
    const over = document.createElement('div');
    over.className = 'world-big';
    over.setAttribute('role', 'dialog');
    over.setAttribute('aria-label', t('world.enlarged'));
    over.style.cssText = 'position:fixed;inset:0;z-index:1000;background:#000c;display:grid;place-items:center;cursor:zoom-out';
    const big = document.createElement('canvas');
    big.style.cssText = 'width:98vw;height:94vh;background:#1d2230;border-radius:8px';
    over.append(big);
    over.addEventListener('click', () => this.enlarge(false));
    const esc = (e) => { if (e.key === 'Escape') { this.enlarge(false); removeEventListener('keydown', esc); } };
    addEventListener('keydown', esc);
    document.body.append(over);
    this.big = big;
    this.dirty = true;
  }

  receive(msg) {
    this.count += 1;
    for (const m of msg?.markers ?? []) {
      if (m.action === DELETEALL) {
        for (const key of [...this.markers.keys()]) {
          if (!m.ns || key.startsWith(`${m.ns}/`)) this.markers.delete(key);
        }
      } else if (m.action === DELETE) {
        this.markers.delete(`${m.ns}/${m.id}`);
      } else {
        this.markers.set(`${m.ns}/${m.id}`, m);
      }
    }
    this.dirty = true;
  }

  // Counts per namespace in the world drawn, for status lines and tests.
  summary() {
    const out = {};
    for (const m of this.visible()) out[m.ns] = (out[m.ns] ?? 0) + 1;
    return out;
  }

  // The map when it belongs to the world drawn (its frame, or no markers at all).
  shownGrid() {
    const g = this.grid;
    return g && (!this.markers.size || frameOf({ header: { frame_id: g.frame } }) === this.current()) ? g : null;
  }

  extent() {
    const shown = this.visible();
    const g = this.shownGrid();
    if (g && !shown.length) return { x0: g.x, y0: g.y, x1: g.x + g.w, y1: g.y + g.h };
    const b = shown.filter((m) => m.ns === 'bounds');
    const src = b.length ? b : shown;
    let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
    const add = (x, y) => { x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y); };
    for (const m of src) {
      const p = m.pose?.position ?? { x: 0, y: 0 };
      if (m.points?.length) for (const q of m.points) add(p.x + q.x, p.y + q.y);
      else if (m.type === CUBE) {
        add(p.x - m.scale.x / 2, p.y - m.scale.y / 2);
        add(p.x + m.scale.x / 2, p.y + m.scale.y / 2);
      } else add(p.x, p.y);
    }
    if (!Number.isFinite(x0) || x1 - x0 < 1e-6) return { x0: 0, y0: 0, x1: 11.0889, y1: 11.0889 };
    return { x0, y0, x1, y1 };
  }

  draw(c = this.canvas) {
    const dpr = window.devicePixelRatio || 1;
    const w = c.clientWidth, h = c.clientHeight;
    if (!w || !h) return;
    if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) {
      c.width = Math.round(w * dpr);
      c.height = Math.round(h * dpr);
    }
    const ctx = c.getContext('2d');
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = '#1d2230';
    ctx.fillRect(0, 0, w, h);
    const e = this.extent();
    const s = Math.min((w - 2 * PAD) / (e.x1 - e.x0), (h - 2 * PAD) / (e.y1 - e.y0));
    if (c === this.canvas) this.fit = { w, h, scale: s, extent: e };
    const ox = (w - s * (e.x1 - e.x0)) / 2 - s * e.x0;
    const oy = (h + s * (e.y1 - e.y0)) / 2 + s * e.y0;
    // world -> canvas: x right, y up
    ctx.setTransform(dpr * s, 0, 0, -dpr * s, dpr * ox, dpr * oy);
    const px = 1 / s;
    const sorted = this.visible().sort((a, b) => (LAYER[a.ns] ?? 4) - (LAYER[b.ns] ?? 4));
    if (!sorted.some((m) => m.ns === 'bounds')) {
      ctx.fillStyle = '#2a3146';
      ctx.fillRect(e.x0, e.y0, e.x1 - e.x0, e.y1 - e.y0);
    }
    for (const m of sorted) if (m.ns === 'bounds') this.drawMarker(ctx, m, px);
    const g = this.shownGrid();
    if (g) {   // over the floor, under the walls; row 0 at the origin: with y up, drawImage puts it at the bottom
      ctx.save();
      ctx.translate(g.x, g.y);
      ctx.rotate(g.yaw);
      ctx.imageSmoothingEnabled = false;
      ctx.drawImage(g.canvas, 0, 0, g.w, g.h);
      ctx.restore();
    }
    for (const m of sorted) if (m.ns !== 'bounds') this.drawMarker(ctx, m, px);
  }

  drawMarker(ctx, m, px) {
    const p = m.pose?.position ?? { x: 0, y: 0 };
    const th = yaw(m.pose?.orientation);
    ctx.save();
    ctx.translate(p.x, p.y);
    ctx.rotate(th);
    const colour = rgba(m.color);
    ctx.fillStyle = colour;
    ctx.strokeStyle = colour;
    ctx.lineCap = 'round';
    const pts = m.points ?? [];
    switch (m.type) {
      case CUBE: case CYLINDER: case SPHERE:
        if (m.ns === 'bounds') {
          ctx.fillRect(-m.scale.x / 2, -m.scale.y / 2, m.scale.x, m.scale.y);
        } else if (m.type === CUBE) {
          ctx.fillRect(-m.scale.x / 2, -m.scale.y / 2, m.scale.x, m.scale.y);
        } else {
          ctx.beginPath();
          ctx.ellipse(0, 0, m.scale.x / 2, m.scale.y / 2, 0, 0, 2 * Math.PI);
          ctx.fill();
        }
        break;
      case LINE_STRIP: case LINE_LIST: {
        ctx.lineWidth = Math.max(m.scale?.x || 0, px);
        ctx.beginPath();
        const step = m.type === LINE_LIST ? 2 : 1;
        for (let i = 0; i + (step - 1) < pts.length; i += step) {
          if (m.type === LINE_LIST) {
            ctx.moveTo(pts[i].x, pts[i].y);
            ctx.lineTo(pts[i + 1].x, pts[i + 1].y);
          } else if (i === 0) ctx.moveTo(pts[i].x, pts[i].y);
          else ctx.lineTo(pts[i].x, pts[i].y);
        }
        if (m.ns === 'bounds') { ctx.fillStyle = FLOOR; ctx.fill(); ctx.lineWidth = Math.max(2 * px, m.scale?.x || 0); }
        ctx.stroke();
        break;
      }
      case POINTS: case SPHERE_LIST: {
        const r = Math.max((m.scale?.x || 0.05) / 2, 1.5 * px);
        pts.forEach((q, i) => {
          if (m.colors?.[i]) ctx.fillStyle = rgba(m.colors[i]);
          ctx.fillRect(q.x - r, q.y - r, 2 * r, 2 * r);
        });
        break;
      }
      case CUBE_LIST: {   // boxes of scale.x by scale.y (a pen raster's runs), at least a pixel
        const rx = Math.max((m.scale?.x || 0.05) / 2, px / 2);
        const ry = Math.max((m.scale?.y || m.scale?.x || 0.05) / 2, px / 2);
        pts.forEach((q, i) => {
          if (m.colors?.[i]) ctx.fillStyle = rgba(m.colors[i]);
          ctx.fillRect(q.x - rx, q.y - ry, 2 * rx, 2 * ry);
        });
        break;
      }
      case ARROW: {
        const len = Math.max(m.scale?.x || 0.5, 12 * px);
        const wid = Math.max(m.scale?.y || len * 0.6, 8 * px);
        ctx.beginPath();
        ctx.moveTo(len / 2, 0);
        ctx.lineTo(-len / 2, wid / 2);
        ctx.lineTo(-len / 4, 0);
        ctx.lineTo(-len / 2, -wid / 2);
        ctx.closePath();
        ctx.fill();
        ctx.lineWidth = px;
        ctx.strokeStyle = '#000';
        ctx.stroke();
        break;
      }
      default: break;
    }
    ctx.restore();
    if (m.text && (m.type === ARROW || m.type === TEXT)) {
      ctx.save();
      ctx.translate(p.x, p.y);
      ctx.scale(px, -px);
      ctx.fillStyle = '#fff';
      ctx.font = '11px system-ui, sans-serif';
      ctx.fillText(m.text, 10, -10);
      ctx.restore();
    }
  }
}
