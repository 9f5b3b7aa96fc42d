// A program opened from another person's share link: data until its opener says to run it, and then
// run without her admin rights. Tried as a class would: a student's link, opened by the teacher,
// ran its JavaScript with her whole session (its Run published a block to the class's library).
//
// - Whose it is: a link carries its sharer's signature (POST api/share, the gateway's own secret:
//   gateway/web/share.py); the page asks the gateway who signed it (api/share/check). A link the
//   opener signed herself is hers; any other, signed or not, is foreign (ide.foreign).
// - Asked first: the first Run (Step, Run on robot) of a foreign program shows whose it is
//   (#dlg-foreign) and runs only on "Run it".
// - No admin rights lent: an admin's page reconnects as an operator (?as=operator, which the gateway
//   honours downwards only) before a foreign program runs, and stays so until it is reloaded; Run on
//   robot asks the gateway for the same ("as": "operator"). A foreign text program does not run in
//   the page: JavaScript in a worker of its own (js/run/guestworker.js), Python in a Pyodide worker of
//   its own (pyrun's guest), each under a policy that gives it no way out but the page's messages
//   (no fetch, no websocket, no import of a page or an API: gateway/web/pages.py GUEST_WORKERS).
//   Its messages reach the gateway through the page's door, as its own programs' do.
import { t } from '../i18n.js';
import { api } from '../link/api.js';

const post = (path, body) => api(path, { method: 'POST', body });

/** The sharer's signature of a program's JSON text: {by, sig} (nulls when the gateway signs nothing). */
export async function signProgram(text) {
  try { return await post('api/share', { text }); } catch { return { by: null, sig: null }; }
}

/** Who signed a link's program: {signed, by, mine}. */
export async function whose(text, shared) {
  if (!shared?.sig || typeof shared.by !== 'string') return { signed: false, by: null, mine: false };
  try { return await post('api/share/check', { text, by: shared.by, sig: shared.sig }); } catch {
    return { signed: false, by: null, mine: false };
  }
}

/** Shows whose the program is and resolves to whether its opener said to run it. */
export function askToRun(foreign) {
  const dlg = document.querySelector('#dlg-foreign');
  document.querySelector('#foreign-whose').textContent = foreign.signed
    ? t('ide.foreign.by', { who: foreign.by }) : t('ide.foreign.unknown');
  dlg.dataset.by = foreign.signed ? foreign.by : '';
  return new Promise((resolve) => {
    const done = (yes) => { dlg.onclose = null; dlg.close(); resolve(yes); };
    document.querySelector('#foreign-run').onclick = () => done(true);
    document.querySelector('#foreign-cancel').onclick = () => done(false);
    dlg.onclose = () => resolve(false);      // Escape
    dlg.showModal();
  });
}

/** The page's way in: asks before a foreign program's first run, and reconnects an admin's page as an
 *  operator first. Resolves to whether the run may go on. */
export function guard(ide, { reconnect }) {
  return async () => {
    const foreign = ide.foreign;
    if (!foreign) return true;
    if (!foreign.confirmed) {
      if (!(await askToRun(foreign))) { ide.console.warn(t('ide.foreign.cancelled')); return false; }
      foreign.confirmed = true;
    }
    if (ide.me?.auth && ide.me.role === 'admin' && !ide.lowered) {
      ide.lowered = true;
      ide.console.info(t('ide.foreign.lowered'));
      await reconnect();
    }
    return true;
  };
}

/** The page's websocket address, as an operator once the page runs another person's program. */
export function asLowered(ide, url) {
  if (!ide.lowered) return url;
  const u = new URL(url, location.href);
  u.searchParams.set('as', 'operator');
  return u.toString();
}

// ---- a JavaScript text program in a worker of its own -------------------------------------------

/**
 * Runs prepared JavaScript (textrun's prepareJs) in js/run/guestworker.js. Its ops pass `door` (the
 * page's RunDoor: what it drove is zeroed when it ends); the page hands it what comes back for them.
 * hooks: log(text, level), line(n), error({line, message, name}), callbacks() (it waits on handlers).
 * Returns {ended: Promise (resolves when it ends), stop()}.
 */
export function runGuest(code, { url, namespace, door, ros, log, line, error, callbacks }) {
  const worker = new Worker(new URL('./guestworker.js', import.meta.url), { type: 'module' });
  const mine = { topics: new Set(), ids: new Set(), services: new Set(), actions: new Set(), goals: new Set() };
  let finish;
  const ended = new Promise((resolve) => { finish = resolve; });
  const relay = (m) => {
    const ours = (m.op === 'publish' && mine.topics.has(m.topic)) || (m.id !== undefined && mine.ids.has(m.id))
      || (m.op === 'call_service' && mine.services.has(m.service))
      || (m.op === 'send_action_goal' && mine.actions.has(m.action)) || (m.op === 'status' && m.id === undefined);
    if (ours) worker.postMessage({ kind: 'frame', msg: m });
    if (m.op === 'action_result') mine.goals.delete(m.id);
  };
  ros.transport?.on('message', relay);
  const stop = () => {
    ros.transport?.off('message', relay);
    for (const id of mine.goals) door.real.callOnConnection({ op: 'cancel_action_goal', id, action: mine.goalActions?.get(id) });
    worker.terminate();
    finish();
  };
  worker.onmessage = (e) => {
    const d = e.data ?? {};
    if (d.kind === 'op' && d.op && typeof d.op === 'object') {
      const op = d.op;
      if (op.op === 'subscribe') mine.topics.add(op.topic);
      if (op.id !== undefined) mine.ids.add(op.id);
      if (op.op === 'advertise_service') mine.services.add(op.service);
      if (op.op === 'advertise_action') mine.actions.add(op.action);
      if (op.op === 'send_action_goal') { mine.goals.add(op.id); (mine.goalActions ??= new Map()).set(op.id, op.action); }
      door._send(op);
    } else if (d.kind === 'log') log(String(d.text), d.level === 'error' ? 'error' : 'log');
    else if (d.kind === 'line') line(Number(d.line));
    else if (d.kind === 'error') { error({ line: d.line ?? null, message: String(d.message), name: d.name }); stop(); }
    else if (d.kind === 'callbacks') callbacks();
    else if (d.kind === 'done') stop();
  };
  worker.onerror = (e) => { e.preventDefault?.(); error({ line: null, message: e.message || 'the program could not start', name: '' }); stop(); };
  worker.postMessage({ kind: 'run', code, url, namespace });
  return { ended, stop };
}
