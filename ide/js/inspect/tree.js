// A message as a folding tree (<details> per nested message): arrays longer than SHOWN items are
// summarised (their length, and for numbers the smallest and largest), byte arrays (base64 in
// JSON) by their size, long strings cut. Nested messages start open (three levels: the numbers of
// an odometry's pose show), arrays folded; a tree drawn again for the next message keeps the
// branches as the reader left them (by their path). Pure helpers (summary, leaves) are exported for tests.
import { t, num } from '../i18n.js';

export const SHOWN = 16;          // array items shown one by one
const OPEN_DEPTH = 3;             // nested messages open at first down to pose.pose.position
const LONG_STRING = 200;

const isList = (v) => Array.isArray(v) || ArrayBuffer.isView(v);

// The one line an array or a byte string stands for when it is too long to show.
export function summary(v, bytes = false) {
  if (typeof v === 'string') {
    const n = bytes ? Math.floor((v.length * 3) / 4) - (v.endsWith('==') ? 2 : v.endsWith('=') ? 1 : 0) : v.length;
    return bytes ? t('inspect.tree.bytes', { n: num(n) }) : t('inspect.tree.chars', { n: num(n) });
  }
  const n = v.length;
  let lo = Infinity, hi = -Infinity, numbers = 0;
  for (const x of v) {
    if (typeof x !== 'number' || !Number.isFinite(x)) continue;
    numbers += 1;
    if (x < lo) lo = x;
    if (x > hi) hi = x;
  }
  if (numbers) return t('inspect.tree.numbers', { n: num(n), min: num(lo), max: num(hi) });
  return t('inspect.tree.items', { n: num(n) });
}

// Every numeric leaf of a message as [path, value] (arrays: their first SHOWN items): what a plot
// may draw.
export function leaves(msg, prefix = '') {
  const out = [];
  if (msg === null || typeof msg !== 'object') return out;
  for (const [k, v] of Object.entries(msg)) {
    const path = prefix ? `${prefix}.${k}` : k;
    if (typeof v === 'number' || typeof v === 'boolean') out.push([path, Number(v)]);
    else if (isList(v)) Array.from(v).slice(0, SHOWN).forEach((x, i) => { if (typeof x === 'number') out.push([`${path}.${i}`, x]); else out.push(...leaves(x, `${path}.${i}`)); });
    else if (v && typeof v === 'object') out.push(...leaves(v, path));
  }
  return out;
}

function scalar(v) {
  const span = document.createElement('span');
  span.className = `v ${v === null ? 'null' : typeof v}`;
  if (typeof v === 'string') span.textContent = JSON.stringify(v.length > LONG_STRING ? `${v.slice(0, LONG_STRING)}…` : v);
  else if (typeof v === 'number') span.textContent = Number.isInteger(v) ? String(v) : String(+v.toPrecision(7));
  else span.textContent = String(v);
  return span;
}

function leaf(key, value) {
  const row = document.createElement('div');
  row.className = 'leaf';
  const k = document.createElement('span');
  k.className = 'k';
  k.textContent = key;
  row.append(k, value);
  return row;
}

export class Tree {
  constructor(el) {
    this.el = el;
    this.open = new Set();         // paths the reader opened
    this.closed = new Set();       // ... and closed (nested messages start open to OPEN_DEPTH, arrays closed)
    this.bytes = new Set();        // fields that are byte arrays (uint8[], char[]: base64 in JSON)
  }

  // fields of the type that hold bytes, from rosapi's typedefs (so their base64 reads as bytes)
  setTypedefs(typedefs) {
    this.bytes = new Set();
    for (const d of typedefs ?? []) {
      d.fieldnames.forEach((name, i) => {
        if (d.fieldarraylen[i] !== -1 && ['uint8', 'char', 'byte'].includes(d.fieldtypes[i])) this.bytes.add(name);
      });
    }
  }

  show(msg) {
    const frag = document.createDocumentFragment();
    this._children(frag, msg, '');
    this.el.replaceChildren(frag);
  }

  _branch(key, value, path) {
    const d = document.createElement('details');
    d.dataset.path = path;
    d.open = this.open.has(path) || (!this.closed.has(path) && !isList(value) && path.split('.').length <= OPEN_DEPTH);
    d.addEventListener('toggle', () => {
      if (d.open) { this.open.add(path); this.closed.delete(path); } else { this.open.delete(path); this.closed.add(path); }
    });
    const s = document.createElement('summary');
    const k = document.createElement('span');
    k.className = 'k';
    k.textContent = key;
    s.append(k);
    if (isList(value)) {
      const n = document.createElement('span');
      n.className = 'n';
      n.textContent = value.length > SHOWN ? summary(value) : `[${value.length}]`;
      s.append(n);
    }
    d.append(s);
    if (d.open) this._children(d, value, path);
    else d.addEventListener('toggle', () => { if (d.open && d.children.length === 1) this._children(d, value, path); }, { once: true });
    return d;
  }

  _children(parent, value, path) {
    const entries = isList(value) ? Array.from(value).slice(0, SHOWN).map((v, i) => [String(i), v]) : Object.entries(value ?? {});
    for (const [k, v] of entries) {
      const p = path ? `${path}.${k}` : k;
      if (typeof v === 'string' && this.bytes.has(k)) {
        const span = document.createElement('span');
        span.className = 'v bytes';
        span.textContent = summary(v, true);
        parent.append(leaf(k, span));
      } else if (v !== null && typeof v === 'object') {
        parent.append(this._branch(k, v, p));
      } else {
        parent.append(leaf(k, scalar(v)));
      }
    }
    if (isList(value) && value.length > SHOWN) {
      const more = document.createElement('div');
      more.className = 'leaf more';
      more.textContent = t('inspect.tree.more', { n: num(value.length - SHOWN) });
      parent.append(more);
    }
  }
}
