// Tells the teacher's view (/class) what this IDE is doing on its robot: a latched
// std_msgs/String on NS/rosgate/program carrying JSON {user, name, state, error, program, at}
// (state: idle | running | paused; error: the last error line; program: the workspace, so the
// teacher can open it read-only). Sent on every run state change and, debounced, on edits.
import { withNamespace } from '../runtime/util.js';

const TYPE = 'std_msgs/msg/String';
const DEBOUNCE = 1500;   // ms after the last edit

export function reportProgram(ide, { workspace, runner, consoleEl }) {
  let ros = null;
  let topic = '';
  let timer = null;
  let lastError = '';
  let user = new URLSearchParams(location.search).get('name') || '';
  if (!user) {
    fetch('whoami').then((r) => (r.ok ? r.json() : {})).then((w) => { user = w.name || ''; }).catch(() => {});
  }

  const send = () => {
    clearTimeout(timer);
    const r = ide.ros;
    if (!r?.isConnected) return;
    const t = withNamespace(ide.ns, '/rosgate/program');
    if (r !== ros || t !== topic) {
      if (ros?.isConnected && topic) ros.callOnConnection({ op: 'unadvertise', topic, id: `advertise:${topic}:report` });
      ros = r;
      topic = t;
      r.callOnConnection({ op: 'advertise', topic, type: TYPE, latch: true, id: `advertise:${topic}:report` });
    }
    let program = null;
    try { program = ide.program(); } catch { /* workspace not ready */ }
    const report = { user, name: ide.programName, state: runner.state, error: lastError, program, at: Date.now() / 1000 };
    r.callOnConnection({ op: 'publish', topic, msg: { data: JSON.stringify(report) } });
  };
  const soon = () => { clearTimeout(timer); timer = setTimeout(send, DEBOUNCE); };

  runner.addEventListener('state', (e) => {
    if (e.detail === 'running') lastError = '';
    send();
  });
  workspace.addChangeListener((e) => { if (!e.isUiEvent) soon(); });
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
  return { send };
}
