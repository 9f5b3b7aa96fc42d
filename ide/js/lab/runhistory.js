// Kept runs (GET api/runs?all=1): every robot-side run the gateway keeps, with its source,
// output and recording to download (api/runs/ID/source, /output, /recording.mcap). A person sees
// their own; an admin everyone's. The IDE's "Runs" dialog lists them (RunHistory); the class view
// shows each student's newest beside their tile (runItem).
import { t, time, day } from '../i18n.js';
import { api } from '../link/api.js';

const ENDED = ['finished', 'failed', 'stopped', 'timed_out'];

export async function keptRuns() {
  return (await api('api/runs', { query: { all: 1 } })).runs;
}

function link(href, text, title) {
  return Object.assign(document.createElement('a'), { href, textContent: text, title, download: '' });
}

// One kept run: its name, when, state (exit code), and its downloads.
export function runItem(run) {
  const li = document.createElement('li');
  li.className = 'kept-run';
  li.dataset.run = run.id;
  li.dataset.state = run.state;
  const when = new Date(run.started * 1000);
  const state = ENDED.includes(run.state) ? t(`robot.state.${run.state}`) : run.state;
  const code = run.exit_code !== null && run.exit_code !== undefined ? t('robot.exit', { code: run.exit_code }) : '';
  const text = Object.assign(document.createElement('span'), {
    textContent: t('runs.item', { name: run.name, when: `${day(when)} ${time(when)}`, state: state + code }),
  });
  if (run.ns) text.title = run.ns;
  const base = `api/runs/${run.id}`;
  li.append(text, ' ', link(`${base}/source`, t('runs.source'), t('runs.source.title')),
    ' ', link(`${base}/output`, t('runs.output'), run.cut ? t('runs.cut', { bytes: run.output_bytes }) : t('runs.output.title')));
  if (run.recorded) li.append(' ', link(`${base}/recording.mcap`, t('runs.recording'), t('runs.recording.title')));
  return li;
}

// The IDE's "Runs" button and dialog (shown when the gateway allows runs).
export class RunHistory {
  constructor(after) {
    this.button = Object.assign(document.createElement('button'), {
      id: 'run-history', hidden: true, textContent: t('runs.history'), title: t('runs.history.title'),
    });
    after?.after(this.button);
    this.dialog = document.createElement('dialog');
    this.dialog.id = 'dlg-runs';
    const heading = Object.assign(document.createElement('h3'), { textContent: t('runs.heading') });
    this.list = Object.assign(document.createElement('ul'), { id: 'runs-list' });
    const close = Object.assign(document.createElement('button'), { textContent: t('page.close') });
    close.onclick = () => this.dialog.close();
    this.dialog.append(heading, this.list, close);
    document.body.append(this.dialog);
    this.button.onclick = () => this.open();
  }

  show(allowed) { this.button.hidden = !allowed; }

  async open() {
    this.list.replaceChildren();
    this.dialog.showModal();
    try {
      const runs = await keptRuns();
      this.list.replaceChildren(...(runs.length ? runs.map(runItem)
        : [Object.assign(document.createElement('li'), { textContent: t('runs.none') })]));
    } catch (e) {
      this.list.replaceChildren(Object.assign(document.createElement('li'), { textContent: t('runs.failed', { error: e.message }) }));
    }
    this.dialog.dataset.loaded = 'yes';
  }
}
