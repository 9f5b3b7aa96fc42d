// The dashboard's plots over a chosen span (10 min, 1 h, 1 day, 7 days, or a day or any span of
// dates and times, shown as it was: no live samples join a span of the past), from the gateway's own
// history (GET api/history: kept whether or not a page was open, see docs/teacher.md), with the
// live samples appended by the dashboard as before. A gateway that keeps no history of a series
// leaves that series as this browser saw it; only the series it lists are asked for.
import { api, ApiError } from '../link/api.js';
import { download } from '../views/download.js';

// span (s) -> the step (s) asked of the gateway: at most ~1000 points a series
export const SPANS = new Map([[600, 1], [3600, 5], [86400, 90], [604800, 600]]);
const POINTS = 1000;   // a chosen span's points a series, at most

/** The step (s) for a span of seconds: a preset's, else whole seconds giving at most POINTS. */
export const stepFor = (span) => SPANS.get(span) ?? Math.max(1, Math.ceil(span / POINTS));

async function fetchSeries(src, from, to, step) {
  const q = new URLSearchParams({ topic: src.topic, field: src.field, from: String(from), to: String(to), step: String(step) });
  let body;
  try { body = await api('api/history', { query: q }); } catch (e) {
    if (e instanceof ApiError) return null;   // no such series kept, or none at all: the page's own samples
    throw e;
  }
  if (!body) return null;
  const scale = src.scale ?? 1;
  const scaled = (a) => (Array.isArray(a) ? a.map((v) => (v === null ? null : v * scale)) : null);
  return { id: src.id, t: body.t, v: scaled(body.v), min: scaled(body.min), max: scaled(body.max) };
}

/** topic -> fields the gateway keeps and this person may read (none when it keeps no history). */
async function keptSeries() {
  try {
    const body = await api('api/history');
    return new Map((body?.series ?? []).map((s) => [s.topic, s.fields]));
  } catch {
    return new Map();
  }
}

/**
 * Rows for `history` (a dashboard.js History) over the last `span` seconds: one row per step,
 * each series' mean there (null where it has none), and its min and max where the gateway
 * gives them (a step of several samples): `${id}:min`, `${id}:max`, drawn as a band.
 * sources: [{id, topic, field, scale}].
 */
export async function loadSpan(history, sources, span, now = Date.now() / 1000, current = () => true) {
  return loadRange(history, sources, now - span, now, current, false);
}

/** As loadSpan, from `from` to `to` (s since 1970); fixed: the chart shows that span alone. */
export async function loadRange(history, sources, from, to, current = () => true, fixed = true) {
  const span = to - from;
  const step = stepFor(span);
  const kept = await keptSeries();
  const wanted = sources.filter((s) => kept.get(s.topic)?.includes(s.field));
  const got = (await Promise.all(wanted.map((s) => fetchSeries(s, from, to, step).catch(() => null))))
    .filter(Boolean);
  if (!got.length && !fixed) return 0;   // no history on the gateway: the browser's own stays
  const keys = new Set();
  for (const r of got) for (const t of r.t) keys.add(Math.floor(t / step));
  const sorted = [...keys].sort((a, b) => a - b);
  const index = new Map(sorted.map((k, i) => [k, i]));
  const rows = { t: sorted.map((k) => (k + 0.5) * step) };
  for (const s of history.series) rows[s.id] = rows.t.map(() => null);
  for (const r of got) {
    if (!rows[r.id]) continue;
    const lo = r.min && (rows[`${r.id}:min`] = rows.t.map(() => null));
    const hi = r.max && (rows[`${r.id}:max`] = rows.t.map(() => null));
    r.t.forEach((t, i) => {
      const at = index.get(Math.floor(t / step));
      rows[r.id][at] = r.v[i];
      if (lo && hi) { lo[at] = r.min[i]; hi[at] = r.max[i]; }
    });
  }
  if (!current()) return 0;   // a newer choice of span was made meanwhile: it draws, not this one
  history.replace(rows, span, fixed ? [from, to] : null);
  return got.length;
}

// <input type=datetime-local> <-> s since 1970 (the page's local time, to the second)
const pad = (n) => String(n).padStart(2, '0');
export function localInput(t) {
  const d = new Date(t * 1000);
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}T${pad(d.getHours())}:${pad(d.getMinutes())}:${pad(d.getSeconds())}`;
}
const fromInput = (v) => new Date(v).getTime() / 1000;

/**
 * The span chooser: a <select> of seconds, or "custom" with a day and from/to inputs (els: {select,
 * range, day, from, to, show, csv, png}); each choice loads its span from the gateway. The CSV and
 * PNG buttons save the span shown (after a zoom: the zoomed one).
 */
export function bindSpan(els, history, sources) {
  const { select } = els;
  let latest = 0;   // the newest load: an older one finishing later (the page's first) is dropped
  const run = (loading) => {
    const mine = ++latest;
    const current = () => mine === latest;
    select.dataset.loading = 'true';
    return loading(current)
      .then((n) => { if (current()) select.dataset.loaded = String(n); })
      .finally(() => { if (current()) delete select.dataset.loading; });
  };
  const load = () => {
    const custom = select.value === 'custom';
    if (els.range) els.range.hidden = !custom;
    if (custom) {
      if (!els.from.value) {   // at first: the last hour, to be changed
        const now = Math.floor(Date.now() / 1000);
        els.from.value = localInput(now - 3600);
        els.to.value = localInput(now);
      }
      return showRange();
    }
    return run((current) => loadSpan(history, sources(), Number(select.value), undefined, current));
  };
  const showRange = () => {
    const from = fromInput(els.from.value), to = fromInput(els.to.value);
    if (!(to > from)) { els.from.setCustomValidity('from < to'); els.from.reportValidity(); return Promise.resolve(); }
    els.from.setCustomValidity('');
    select.dataset.from = String(from);
    select.dataset.to = String(to);
    return run((current) => loadRange(history, sources(), from, to, current));
  };
  select.addEventListener('change', load);
  els.show?.addEventListener('click', showRange);
  els.day?.addEventListener('change', () => {   // a whole day, midnight to midnight
    if (!els.day.value) return;
    const day = new Date(`${els.day.value}T00:00:00`);
    els.from.value = localInput(day.getTime() / 1000);
    day.setDate(day.getDate() + 1);
    els.to.value = localInput(day.getTime() / 1000);
    showRange();
  });
  const stamp = () => localInput(history.span()[0]).replace(/[:T]/g, '-');
  els.csv?.addEventListener('click', () => download(`history-${stamp()}.csv`, history.csv(), 'text/csv'));
  els.png?.addEventListener('click', async () => download(`history-${stamp()}.png`, await history.png()));
  return load;
}
