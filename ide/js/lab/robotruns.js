// "Run on robot": the program's generated Python runs as a process next to the robot
// (POST /api/runs), so it keeps going when this tab sleeps or the Wi-Fi drops. Its output
// streams into the console from /rosgate/runs/ID/output; Stop ends it (DELETE /api/runs/ID).
// The button only appears when the gateway allows runs (--allow-runs). Reopening the page
// re-attaches to the runs in progress. "Record" beside it records the station's topics for the
// run's length (an MCAP kept with the run); "Runs" lists every kept run (js/lab/runhistory.js).
import { Topic } from 'roslib';
import { t } from '../i18n.js';
import { RunHistory } from './runhistory.js';
import { api } from '../link/api.js';

const STRING = 'std_msgs/msg/String';
const ACTIVE = new Set(['starting', 'running']);

const runs = (path = '', options = {}) => api(`api/runs${path}`, options);

export class RobotRuns extends EventTarget {
  // ide: { console, generatePython(), programName, ns, ros }
  constructor(ide) {
    super();
    this.ide = ide;
    this.followed = new Map();   // run id -> { topics, run }
    this.ros = null;
    this.button = Object.assign(document.createElement('button'), {
      id: 'run-robot', className: 'go', hidden: true, textContent: t('robot.run'),
      title: t('robot.run.title'),
    });
    document.querySelector('#run')?.after(this.button);
    this.record = Object.assign(document.createElement('label'), { id: 'run-record', hidden: true, title: t('robot.record.title') });
    this.record.append(Object.assign(document.createElement('input'), { type: 'checkbox' }), ` ${t('robot.record')}`);
    this.button.after(this.record);
    this.history = new RunHistory(this.record);
    this.button.onclick = () => this.start();
    document.querySelector('#stop')?.addEventListener('click', () => this.stop());
    this._setState();
  }

  // Asks whether the gateway allows runs; shows the button and re-attaches to runs in progress.
  async init() {
    let listing;
    try { listing = await runs(); } catch { return; }
    this.allowed = Boolean(listing.allowed);
    this.nodes = Boolean(listing.nodes);     // runs join the ROS graph: a program runs as its ROS 2 node
    this.button.hidden = !this.allowed;
    this.record.hidden = !this.allowed;
    this.history.show(this.allowed);
    document.body.dataset.robotRuns = this.allowed ? 'allowed' : 'off';
    const active = listing.runs.filter((r) => ACTIVE.has(r.state));
    for (const run of active) this.ide.console.info(t(run.ns ? 'robot.running.in' : 'robot.running', { id: run.id, name: run.name, ns: run.ns }));
    const mine = active.filter((r) => r.ns === (this.ide.ns || ''));
    for (const run of mine) await this.attach(run, { replay: true });
  }

  // Called by the page on every (re)connection of its rosbridge client.
  connected(ros) {
    this.ros = ros;
    for (const [id, f] of this.followed) { this._unsubscribe(f); this._subscribe(id, f); }
  }

  async start() {
    const why = this.ide.robotNs?.whyNot();
    if (why) { this.ide.console.error(t('robot.run.failed', { why })); return; }
    if (this.ide.mayRun && !(await this.ide.mayRun())) return;   // another person's program: asked first (js/run/foreign.js)
    let source;
    let kind = 'python';
    try {
      // where runs are nodes of the ROS graph, a block program (or an rclpy one) runs as its ROS 2 node
      const node = this.nodes ? await this.ide.rosNode?.() : null;
      if (node) { source = node; kind = 'ros2_node'; } else source = this.ide.generatePython();
    } catch (e) { this.ide.console.error(t('robot.codegen.failed', { error: e.message })); return; }
    try {
      const run = await runs('', {
        method: 'POST',
        body: {
          source, kind, name: this.ide.programName, ns: this.ide.ns || '', timeout: 600,
          record: this.record.querySelector('input').checked,
          ...(this.ide.foreign ? { as: 'operator' } : {}),     // with no admin rights lent
        },
      });
      await this.attach(run, { replay: false });
    } catch (e) { this.ide.console.error(t('robot.run.failed', { why: e.message })); }
  }

  async stop() {
    for (const id of this.followed.keys()) {
      try { await runs(`/${id}`, { method: 'DELETE' }); } catch (e) { this.ide.console.error(t('robot.stop.failed', { id, error: e.message })); }
    }
  }

  async attach(run, { replay }) {
    if (this.followed.has(run.id)) return;
    const f = { run, topics: [], pending: [], ready: !replay };
    this.followed.set(run.id, f);
    this.ide.console.info(t('robot.attached', { id: run.id }));
    this._subscribe(run.id, f);
    if (replay) {   // what it printed before this page opened, then what arrived meanwhile
      try {
        const detail = await runs(`/${run.id}`);
        for (const line of detail.output.split('\n').slice(0, -1)) this._print(line);
      } catch (e) { this.ide.console.error(e.message); }
      f.ready = true;
      f.pending = [];
    }
    this._setState();
  }

  _subscribe(id, f) {
    if (!this.ros) return;
    const output = new Topic({ ros: this.ros, name: `/rosgate/runs/${id}/output`, messageType: STRING });
    output.subscribe((m) => { if (f.ready) this._print(m.data); else f.pending.push(m.data); });
    const state = new Topic({ ros: this.ros, name: `/rosgate/runs/${id}/state`, messageType: STRING });
    state.subscribe((m) => this._state(id, JSON.parse(m.data)));
    f.topics = [output, state];
  }

  _unsubscribe(f) {
    for (const t of f.topics) { try { t.unsubscribe(); } catch { /* the connection is gone */ } }
    f.topics = [];
  }

  _print(line) {
    if (/^\[run (finished|failed|stopped|timed_out)/.test(line)) return;   // said by _state
    this.ide.console.log(line);
  }

  _state(id, run) {
    const f = this.followed.get(id);
    if (!f) return;
    f.run = run;
    if (ACTIVE.has(run.state)) { this._setState(); return; }
    this._unsubscribe(f);
    this.followed.delete(id);
    const known = ['finished', 'failed', 'stopped', 'timed_out'].includes(run.state);
    const text = t('robot.ended', { id, state: known ? t(`robot.state.${run.state}`) : run.state }) + (run.reason ? `: ${run.reason}` : '')
      + (run.exit_code !== null && run.exit_code !== undefined ? t('robot.exit', { code: run.exit_code }) : '');
    if (run.state === 'failed') this.ide.console.error(text); else this.ide.console.info(text);
    this._setState();
  }

  _setState() {
    const running = this.followed.size > 0;
    document.body.dataset.robotRun = running ? 'running' : 'idle';
    this.dispatchEvent(new CustomEvent('state', { detail: running ? 'running' : 'idle' }));
  }
}
