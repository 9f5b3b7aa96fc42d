// An exercise in the IDE (?exercise=ID): its start program is loaded, and "Start attempt" asks the
// gateway to watch the goal on this page's station (POST api/exercises/ID/attempts) and runs the
// program through the page's own Run. The gateway checks the goal on the robot's own topics and ends
// the attempt at the goal, the time limit, or here when the program stops (POST .../stop); the
// result shown is the gateway's (GET api/attempts/ID), never the page's own judgement. Its title and
// instructions are in the reader's language where the exercise gives one; the instructions (Markdown)
// stand beside the editor, rendered by markdown-it with HTML off: a teacher's <script> or
// <img onerror> shows as the text it is, and a javascript: link is no link.
import * as storage from '../editors/storage.js';
import { t, localized } from '../i18n.js';
import { api } from '../link/api.js';

const POLL = 500;   // ms between looks at a live attempt

const post = (url, body) => api(url, { method: 'POST', body: body ?? {} });

function startProgram(ex, title) {
  const start = ex.start ?? {};
  if (start.blocks) return { ...start.blocks, name: start.blocks.name || title };
  if (typeof start.text === 'string') return storage.makeTextProgram({ name: title, lang: 'python', text: start.text });
  if (start.text) return storage.makeTextProgram({ name: title, lang: start.text.lang || 'python', text: start.text.text || '' });
  return null;
}

// The exercise's title in the reader's language.
export function titleOf(ex) {
  return localized(ex.titles && Object.keys(ex.titles).length ? { en: ex.title, ...ex.titles } : ex.title);
}

// The instructions beside the editor (at the top of the side panel); null when there are none.
export async function showInstructions(ex, title) {
  const text = localized(ex.instructions);
  if (!text) return null;
  const { default: MarkdownIt } = await import('../../vendor/markdown-it.mjs');
  const md = new MarkdownIt({ html: false, linkify: true });
  const render = md.renderer.rules.link_open ?? ((tokens, i, options, env, self) => self.renderToken(tokens, i, options));
  md.renderer.rules.link_open = (tokens, i, options, env, self) => {   // a link opens beside the IDE, not over it
    tokens[i].attrSet('target', '_blank');
    tokens[i].attrSet('rel', 'noopener noreferrer');
    return render(tokens, i, options, env, self);
  };
  const panel = document.createElement('section');
  panel.id = 'instructions';
  panel.setAttribute('aria-label', t('ide.ex.instructions'));
  const heading = Object.assign(document.createElement('h2'), { textContent: title });
  const body = Object.assign(document.createElement('div'), { className: 'markdown' });
  body.innerHTML = md.render(text);   // markdown-it's own HTML: the text's own is escaped (html: false)
  panel.append(heading, body);
  document.querySelector('#side').prepend(panel);
  return panel;
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
  try { ex = await api(`api/exercises/${encodeURIComponent(id)}`); } catch (e) {
    status.textContent = t('ide.ex.missing', { id, error: e.message });
    button.disabled = true;
    return null;
  }
  const title = titleOf(ex);
  button.title = t('ide.ex.start.title', { title, seconds: ex.time_limit });
  status.textContent = title;
  const start = startProgram(ex, title);
  if (start) await ide.loadProgram(start);
  await showInstructions(ex, title).catch((e) => ide.console?.warn(e.message));
  let attempt = null;
  const show = (r) => {
    document.body.dataset.attempt = r.live ? 'live' : (r.passed ? 'passed' : 'failed');
    status.textContent = r.live ? t('ide.ex.live', { title })
      : t(r.passed ? 'ide.ex.passed' : 'ide.ex.failed', { title, score: `${Math.round(r.score * 100)}%` });
  };
  const follow = async (which) => {
    while (attempt === which) {
      let r;
      try { r = await api(`api/attempts/${which}`); } catch (e) { status.textContent = e.message; return; }
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
