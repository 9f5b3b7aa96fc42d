// Tells the teacher's view (/class) what this IDE is doing on its robot: a latched
// std_msgs/String on NS/rosgate/program carrying JSON {user, name, state, error, program, line, at}
// (state: idle | running | paused; error: the last error line; program: the program (blocks or
// text), so the teacher can open it read-only; line: the line a text program runs at, or null). Sent on every run state change and, debounced, on edits.
// The error is the present one: cleared by a run, a Take (the page drives again), a new program
// and a change of station (an error about /s01 is never reported on /s02); the teacher's stop and
// the page's own notes (console warnings) are not errors.
import { withNamespace } from '../../runtime/util.js';
import { api } from '../link/api.js';

const TYPE = 'std_msgs/msg/String';
const DEBOUNCE = 1500;   // ms after the last edit

const LINE_EVERY = 500;  // ms between reports of a text program's running line

export function reportProgram(ide, { workspace, runners, consoleEl }) {
  const state = () => runners.find((r) => r.state !== 'idle')?.state ?? 'idle';
  let line = null;
  let ros = null;
  let topic = '';
  let timer = null;
  let lastError = '';
  let user = new URLSearchParams(location.search).get('name') || '';
  if (!user) {
    api('whoami').then((w) => { user = w?.name || ''; }).catch(() => {});
  }

  const send = () => {
    clearTimeout(timer);
    const r = ide.ros;
    if (!r?.isConnected) return;
    const t = withNamespace(ide.ns, '/rosgate/program');
    if (r !== ros || t !== topic) {
      if (t !== topic) lastError = '';
      if (ros?.isConnected && topic) {
        if (t !== topic) {   // the station left behind keeps no program of this page's
          ros.callOnConnection({ op: 'publish', topic, msg: { data: JSON.stringify({ user, name: '', state: 'none', error: '', program: null, at: Date.now() / 1000 }) } });
        }
        ros.callOnConnection({ op: 'unadvertise', topic, id: `advertise:${topic}:report` });
      }
      ros = r;
      topic = t;
      r.callOnConnection({ op: 'advertise', topic, type: TYPE, latch: true, id: `advertise:${topic}:report` });
    }
    let program = null;
    try { program = ide.program(); } catch { /* workspace not ready */ }
    const report = { user, name: ide.programName, state: state(), error: lastError, program, line, at: Date.now() / 1000 };
    r.callOnConnection({ op: 'publish', topic, msg: { data: JSON.stringify(report) } });
  };
  const soon = () => { clearTimeout(timer); timer = setTimeout(send, DEBOUNCE); };

  let lineTimer = null;
  for (const runner of runners) {
    runner.addEventListener('state', (e) => {
      if (e.detail === 'running') lastError = '';
      if (e.detail === 'idle') line = null;
      send();
    });
    runner.addEventListener('line', (e) => {      // a text program's running line, twice a second
      line = e.detail;
      lineTimer ??= setTimeout(() => { lineTimer = null; if (state() !== 'idle') send(); }, LINE_EVERY);
    });
  }
  workspace.addChangeListener((e) => { if (!e.isUiEvent) soon(); });
  let driving = false;      // the page (or another of this person's) drives: a Take clears the error
  ide.lease?.addEventListener('change', () => {
    const now = ['you', 'yours'].includes(ide.lease.state);
    if (now && !driving && lastError) { lastError = ''; send(); }
    driving = now;
  });
  new MutationObserver((records) => {
    for (const rec of records) {
      for (const node of rec.addedNodes) {
        if (node.classList?.contains('error')) {
          lastError = [...node.childNodes].filter((n) => n.nodeType === Node.TEXT_NODE).map((n) => n.textContent).join('').trim();
          soon();
        }
      }
    }
  }).observe(consoleEl, { childList: true });
  setInterval(() => {       // a new connection or robot: report at once
    if (ide.ros?.isConnected && (ide.ros !== ros || withNamespace(ide.ns, '/rosgate/program') !== topic)) send();
  }, 1000);
  // A new program: what went wrong with the last one is behind.
  const clear = () => { lastError = ''; send(); };
  return { send, clear, edited: soon };
}
