// Recordings on the IDE and the teleop page: a record button that shows the elapsed time and
// size while it records, and a dialog with the topics to record and the list of recordings
// (download as .mcap, play back into the graph). HTTP only (/api/recordings), so the same
// module serves both pages: the page's module mounts it into its #bar (mountRecorder).
// On a page with a robot (a fleet's station, the #ns field) a name typed without it records the
// station's topic too ('/turtle1/pose' also asks for /s07/turtle1/pose), as the blocks do; a
// recording that matches no topic, or ends with no message, says so.
import { t, num } from '../i18n.js';
import { api } from '../link/api.js';

const TOPICS_KEY = 'rosgate.recTopics';
// the topics last recorded; none where the page may not keep anything (an LMS's frame)
const stored = () => { try { return localStorage.getItem(TOPICS_KEY) || ''; } catch { return ''; } };

export const formatBytes = (n) => (n < 1024 ? `${n} B` : n < 2 ** 20 ? `${(n / 1024).toFixed(1)} KB`
  : `${(n / 2 ** 20).toFixed(1)} MB`);
export const formatElapsed = (s) => `${Math.floor(s / 60)}:${String(Math.floor(s % 60)).padStart(2, '0')}`;

const recordings = (path, options = {}) => api(`api/recordings${path}`, options);

// Who this page is signed in as ({auth, name, role}; null when the gateway does not say): with
// --auth a recording is its starter's (and the admins') to stop, play and download.
const whoami = () => api('whoami').catch(() => null);

const el = (tag, props = {}, ...children) => {
  const e = Object.assign(document.createElement(tag), props);
  e.append(...children);
  return e;
};

export class Recorder {
  constructor(bar) {
    this.current = null;      // id of the recording this page shows in its button
    this.timer = null;
    this.me = null;
    this.button = el('button', { id: 'rec', className: 'rec', title: t('rec.title'), textContent: t('rec.button') });
    this.listButton = el('button', { id: 'recordings', title: t('rec.list.title'), textContent: t('rec.list') });
    bar.append(el('span', { className: 'group recorder' }, this.button, this.listButton));
    this.topics = el('input', { id: 'rec-topics', size: 28, value: stored() });
    this.message = el('p', { className: 'rec-msg' });
    this.list = el('ul', { id: 'rec-list' });
    const close = el('button', { textContent: t('page.close'), onclick: () => this.dialog.close() });
    this.dialog = el('dialog', { id: 'dlg-recordings' },
      el('h3', { textContent: t('rec.list') }),
      el('label', {}, t('rec.topics'), ' ', this.topics),
      this.message, this.list, el('p', {}, close));
    document.body.append(this.dialog);
    this.button.onclick = () => (this.current ? this.stop() : this.start());
    this.listButton.onclick = () => { this.dialog.showModal(); this.refresh(); };
    this.topics.onchange = () => { try { localStorage.setItem(TOPICS_KEY, this.topics.value); } catch { /* storage off */ } };
  }

  // The page's robot namespace ('/s07'), or ''.
  namespace() {
    const ns = (document.querySelector('#ns')?.value || '').trim().replace(/\/+$/, '');
    return ns ? `${ns.startsWith('/') ? '' : '/'}${ns}` : '';
  }

  defaultTopics() {
    const ns = this.namespace();
    return ns ? `${ns}/*` : '/*';
  }

  // What to ask the gateway for: the typed names (or the default), each also in the station.
  requested() {
    const ns = this.namespace();
    const typed = (this.topics.value.trim() || this.defaultTopics()).split(/[\s,]+/).filter(Boolean);
    const out = [];
    for (const t of typed) {
      out.push(t);
      if (ns && t.startsWith('/') && t !== ns && !t.startsWith(`${ns}/`)) out.push(`${ns}${t}`);
    }
    return [...new Set(out)];
  }

  // Why a recording records nothing: no topic matches, and (on a fleet) no robot chosen.
  nothingText(rec) {
    const fleet = document.querySelector('#claim')?.hidden === false;
    const station = !this.namespace() && fleet ? ` ${t('rec.no.robot')}` : '';
    return t('rec.no.match', { topics: rec.requested.join(' ') }) + station;
  }

  mine(rec) {
    const me = this.me;
    return !me?.auth || me.role === 'admin' || !rec.owner || rec.owner === me.name;
  }

  say(text, error = false) {
    this.message.textContent = text;
    this.message.classList.toggle('error', error);
  }

  async start() {
    const topics = this.requested();
    try {
      const rec = await recordings('', { method: 'POST', body: { topics, max_seconds: 600 } });
      this.follow(rec);
      if (!rec.topics.length) {           // it waits for such topics; say so at once
        this.say(this.nothingText(rec), true);
        this.dialog.showModal();
        this.refresh();
      }
    } catch (e) {
      this.say(t('rec.failed', { error: e.message }), true);
      this.dialog.showModal();
    }
  }

  async stop() {
    if (!this.current) return;
    try { this.show(await recordings(`/${this.current}`, { method: 'DELETE' })); } catch (e) { this.say(e.message, true); }
  }

  // Shows a running recording in the button until it ends (also one found when the page opens).
  follow(rec) {
    this.current = rec.id;
    clearInterval(this.timer);
    this.timer = setInterval(async () => {
      try { this.show(await recordings(`/${rec.id}`)); } catch { /* the next tick tries again */ }
    }, 1000);
    this.show(rec);
  }

  show(rec) {
    const recording = rec.state === 'recording';
    document.body.dataset.recording = recording ? 'on' : 'off';
    this.button.classList.toggle('on', recording);
    this.button.classList.toggle('empty', recording && !rec.topics.length);
    if (recording) {
      const none = !rec.topics.length;
      this.button.textContent = `■ ${formatElapsed(Date.now() / 1000 - rec.started)} · ${none ? t('rec.no.topics') : formatBytes(rec.bytes)}`;
      this.button.title = none ? `${this.nothingText(rec)} ${t('rec.press.stop')}`
        : t('rec.recording', { topics: rec.topics.join(', ') });
      return;
    }
    clearInterval(this.timer);
    this.current = null;
    this.button.textContent = t('rec.button');
    this.button.title = t('rec.title');
    const empty = rec.messages === 0;
    this.say(t('rec.done', { id: rec.id, n: rec.messages ?? '?', size: formatBytes(rec.bytes) }) + (rec.reason ? ` (${rec.reason})` : '')
      + (!empty ? '' : rec.topics?.length ? t('rec.nothing.came', { topics: rec.topics.join(', ') }) : `. ${this.nothingText(rec)}`), empty);
    if (this.dialog.open) this.refresh();
  }

  async refresh() {
    if (!this.topics.value) this.topics.placeholder = this.defaultTopics();
    let items;
    try { items = (await recordings('')).recordings; } catch (e) { this.list.textContent = t('rec.unavailable', { error: e.message }); return; }
    this.list.replaceChildren(...items.slice().reverse().map((rec) => {
      const li = el('li', { id: `rec-${rec.id}` }, `${rec.id} · ${formatBytes(rec.bytes)}${rec.owner ? ` · ${rec.owner}` : ''} `);
      if (rec.state === 'recording') {
        li.append(el('b', { textContent: t('rec.running') }));
        return li;
      }
      if (!this.mine(rec)) return li;
      li.append(el('a', { href: `api/recordings/${rec.id}.mcap`, download: `${rec.id}.mcap`, textContent: t('rec.download') }), ' ');
      li.append(el('button', {
        textContent: t('rec.play'), title: t('rec.play.title'),
        onclick: async () => {
          try {
            const p = await recordings(`/${rec.id}/play`, { method: 'POST', body: { rate: 1 } });
            this.say(t('rec.playing', { n: p.messages, s: num(p.duration, 1) }));
          } catch (e) { this.say(e.message, true); }
        },
      }));
      return li;
    }));
    if (!items.length) this.list.textContent = t('rec.none');
  }

  async attach() {
    try {
      this.me = await whoami();
      // a page's own kind of recording (not the gateway's --record one, which has no max_seconds)
      const running = (await recordings('')).recordings.filter((r) => r.state === 'recording' && r.max_seconds && this.mine(r));
      if (running.length) this.follow(running[running.length - 1]);
    } catch { /* no recordings API: the button still tries when pressed */ }
  }
}

// The page's one module mounts it (js/ide/main.js, js/teleop/main.js): no module of the pages does work
// when imported, so what a page shows does not hang on the order an engine evaluates modules in.
export function mountRecorder(bar = document.querySelector('#bar')) {
  if (!bar) return null;
  const recorder = new Recorder(bar);
  recorder.attach();
  return recorder;
}
