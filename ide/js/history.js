// The dashboard's plots over a chosen span (10 min, 1 h, 1 day, 7 days), from the gateway's own
// history (GET api/history: kept whether or not a page was open, see docs/teacher.md), with the
// live samples appended by the dashboard as before. A gateway that keeps no history of a series
// leaves that series as this browser saw it; only the series it lists are asked for.

// span (s) -> the step (s) asked of the gateway: at most ~1000 points a series
export const SPANS = new Map([[600, 1], [3600, 5], [86400, 90], [604800, 600]]);

async function fetchSeries(src, from, to, step) {
  const q = new URLSearchParams({ topic: src.topic, field: src.field, from: String(from), to: String(to), step: String(step) });
  const res = await fetch(`api/history?${q}`, { credentials: 'same-origin' });
  if (!res.ok) return null;
  const body = await res.json();
  const scale = src.scale ?? 1;
  const scaled = (a) => (Array.isArray(a) ? a.map((v) => (v === null ? null : v * scale)) : null);
  return { id: src.id, t: body.t, v: scaled(body.v), min: scaled(body.min), max: scaled(body.max) };
}

/** topic -> fields the gateway keeps and this person may read (none when it keeps no history). */
async function keptSeries() {
  try {
    const res = await fetch('api/history', { credentials: 'same-origin' });
    if (!res.ok) return new Map();
    const body = await res.json();
    return new Map((body.series ?? []).map((s) => [s.topic, s.fields]));
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
  const step = SPANS.get(span) ?? 1;
  const kept = await keptSeries();
  const wanted = sources.filter((s) => kept.get(s.topic)?.includes(s.field));
  const got = (await Promise.all(wanted.map((s) => fetchSeries(s, now - span, now, step).catch(() => null))))
    .filter(Boolean);
  if (!got.length) return 0;   // no history on the gateway: the browser's own stays
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
  history.replace(rows, span);
  return got.length;
}

/** The span chooser (a <select> of seconds): each choice loads that span from the gateway. */
export function bindSpan(select, history, sources) {
  let latest = 0;   // the newest load: an older one finishing later (the page's first) is dropped
  const load = () => {
    const span = Number(select.value);
    const mine = ++latest;
    const current = () => mine === latest;
    select.dataset.loading = 'true';
    return loadSpan(history, sources(), span, undefined, current)
      .then((n) => { if (current()) select.dataset.loaded = String(n); })
      .finally(() => { if (current()) delete select.dataset.loading; });
  };
  select.addEventListener('change', load);
  return load;
}
