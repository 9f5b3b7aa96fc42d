// An exercise in the IDE (?exercise=ID): its start program is loaded, and "Start attempt" asks the
// gateway to watch the goal on this page's station (POST api/exercises/ID/attempts) and runs the
// program through the page's own Run. The gateway checks the goal on the robot's own topics and ends
// the attempt at the goal, the time limit, or here when the program stops (POST .../stop); the
// result shown is the gateway's (GET api/attempts/ID), never the page's own judgement.
import * as storage from './storage.js';
import { t } from './i18n.js';

const POLL = 500;   // ms between looks at a live attempt

async function json(url, options) {
  const res = await fetch(url, { cache: 'no-store', ...options });
  const body = await res.json().catch(() => null);
  if (!res.ok) throw new Error(body?.error || `HTTP ${res.status}`);
  return body;
}

const post = (url, body) => json(url, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body ?? {}) });

function startProgram(ex) {
  const start = ex.start ?? {};
  if (start.blocks) return { ...start.blocks, name: start.blocks.name || ex.title };
  if (typeof start.text === 'string') return storage.makeTextProgram({ name: ex.title, lang: 'python', text: start.text });
  if (start.text) return storage.makeTextProgram({ name: ex.title, lang: start.text.lang || 'python', text: start.text.text || '' });
  return null;
}

// Mounts the bar's exercise part; resolves to the exercise (or null without ?exercise=).
export async function mountExercise(ide, { runners, runButton, say }) {
  const id = new URLSearchParams(location.search).get('exercise');
  if (!id) return null;
  const bar = document.createElement('span');
  bar.className = 'group exercise';
  const button = Object.assign(document.createElement('button'), { id: 'exercise-start', textContent: t('ide.ex.start') });
  const status = Object.assign(document.createElement('span'), { id: 'exercise-status' });
  bar.append(button, ' ', status);
  runButton.closest('.group').after(bar);
  let ex;
  try { ex = await json(`api/exercises/${encodeURIComponent(id)}`); } catch (e) {
    status.textContent = t('ide.ex.missing', { id, error: e.message });
    button.disabled = true;
    return null;
  }
  button.title = t('ide.ex.start.title', { title: ex.title, seconds: ex.time_limit });
  status.textContent = ex.title;
  const start = startProgram(ex);
  if (start) await ide.loadProgram(start);
  let attempt = null;
  const show = (r) => {
    document.body.dataset.attempt = r.live ? 'live' : (r.passed ? 'passed' : 'failed');
    status.textContent = r.live ? t('ide.ex.live', { title: ex.title })
      : t(r.passed ? 'ide.ex.passed' : 'ide.ex.failed', { title: ex.title, score: `${Math.round(r.score * 100)}%` });
  };
  const follow = async (which) => {
    while (attempt === which) {
      let r;
      try { r = await json(`api/attempts/${which}`); } catch (e) { status.textContent = e.message; return; }
      show(r);
      if (!r.live) { attempt = null; button.disabled = false; say?.(status.textContent); return; }
      await new Promise((ok) => setTimeout(ok, POLL));
    }
  };
  // the program stopped (or ended) while the attempt goes on: the attempt ends with it
  for (const runner of runners) {
    runner.addEventListener('state', (e) => {
      if (e.detail !== 'idle' || !attempt || runners.some((r) => r.state !== 'idle')) return;
      post(`api/attempts/${attempt}/stop`).catch(() => {});   // already ended at its goal: nothing to stop
    });
  }
  button.onclick = async () => {
    button.disabled = true;
    try {
      const program = JSON.stringify(ide.program());
      const name = new URLSearchParams(location.search).get('name') || '';   // a student's name, without sign-in
      const r = await post(`api/exercises/${encodeURIComponent(ex.id)}/attempts`, { station: ide.ns || '', program, name });
      attempt = r.attempt;
      show({ live: true });
      runButton.click();
      follow(r.attempt);
    } catch (e) {
      status.textContent = t('ide.ex.refused', { error: e.message });
      button.disabled = false;
    }
  };
  ide.exercise = { ex, get attempt() { return attempt; } };
  return ex;
}
