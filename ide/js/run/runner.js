// Runs the workspace's JavaScript live: Run, Pause, Step, Stop, highlighting, and
// errors shown on the block that raised them.
/* global Blockly */
import { Runtime, StopSignal } from '../../runtime/runtime.js';
import { gen as jsGen } from '../../generators/javascript.js';
import { t, tn } from '../i18n.js';

const AsyncFunction = Object.getPrototypeOf(async () => {}).constructor;

export class Runner extends EventTarget {
  constructor(workspace, getRos, console_, getNamespace = () => '', { ready = async () => {}, loose = () => [] } = {}) {
    super();
    this.ready = ready;          // resolves when the page knows enough to write the run's names
    this.loose = loose;          // the loose blocks the run skips
    this.workspace = workspace;
    this.getRos = getRos;
    this.getNamespace = getNamespace;
    this.console = console_;
    this.rt = null;
    this.state = 'idle';         // idle | running | paused
    this.errors = new Map();     // block id -> message
    this.runs = 0;
    this.starting = 0;           // the run waiting for the graph before its first block (0: none)
    this.heldAt = null;          // block the paused program holds at (null while a block runs)
    addEventListener('pagehide', () => this.rt?.stop());
  }

  _setState(s) {
    this.state = s;
    this.dispatchEvent(new CustomEvent('state', { detail: s }));
  }

  clearErrors() {
    for (const id of this.errors.keys()) this.workspace.getBlockById(id)?.setWarningText(null);
    this.errors.clear();
  }

  async run({ paused = false, step = false } = {}) {
    if (this.rt || this.starting) this.stop();
    const ros = this.getRos();
    if (!ros?.isConnected) {
      this.console.error(t('run.not.connected'));
      return;
    }
    this.clearErrors();
    const run = ++this.runs;
    // the run is under way from the press (Stop works) while the page reads the graph for its names
    this.starting = run;
    this._setState(paused || step ? 'paused' : 'running');
    await this.ready();
    if (this.starting !== run) return;       // stopped, or Run or Step pressed again, meanwhile
    this.starting = 0;
    let code;
    try {
      code = jsGen.generate(this.workspace, { instrument: true });
    } catch (e) {
      this.console.error(t('run.codegen.failed', { error: e.message }));
      this._setState('idle');
      return;
    }
    const rt = new Runtime(ros, {
      log: (text, level) => this.console.log(text, level),
      highlight: (id) => { if (this.rt === rt) this.workspace.highlightBlock(id); },
      error: (e, id) => this._error(rt, e, id),
      held: (id) => this._held(rt, id),
    }, { namespace: this.getNamespace() });
    this.rt = rt;
    if (paused) rt.pause();
    this.pendingStep = step;                 // the first Step runs the first block too
    if (step) rt.stepOnce();
    this.console.info(t(paused || step ? 'run.started.step' : 'run.started', { run }));
    const loose = this.loose().length;
    if (loose) this.console.info(tn('run.loose', loose));
    let fn;
    try {
      fn = new AsyncFunction('rt', code);
    } catch (e) {
      this._error(rt, e, null);
      return;
    }
    try {
      await fn(rt);
      if (this.rt !== rt || rt.stopped) return;
      if (rt.listening()) {
        this.console.info(t('run.handlers'));
        return;
      }
      await rt.settle();           // an error about the last block's publish still ends on its block
      if (this.rt !== rt || rt.stopped) return;
      this._finish(rt, t('run.finished', { run }));
    } catch (e) {
      if (e instanceof StopSignal) return;
      this._error(rt, e, rt.current);
    }
  }

  // The program holds before a block. While stepping it does not hold at a block that only holds
  // others (a loop, an if): a press of Step moves a block that does something, the first press too.
  _held(rt, id) {
    if (this.rt !== rt) return;
    const block = this.workspace.getBlockById(id);
    if (rt.stepping && block?.inputList.some((i) => i.connection?.type === Blockly.ConnectionType.NEXT_STATEMENT)) {
      rt.stepOnce();
      return;
    }
    if (this.pendingStep) {
      this.pendingStep = false;
      this.console.info(block ? t('run.step.block', { block: blockText(block) }) : t('run.step'));
      rt.stepOnce();
      return;
    }
    this.heldAt = id;
    this.dispatchEvent(new CustomEvent('held', { detail: id }));
  }

  _error(rt, e, blockId) {
    if (this.rt !== rt || rt.stopped) return;
    const block = blockId ? this.workspace.getBlockById(blockId) : null;
    const msg = e?.message ?? String(e);
    this.console.error(msg, blockId);
    if (block) {
      this.errors.set(blockId, msg);
      block.setWarningText(msg);
      const icon = block.getIcon?.(Blockly.icons.IconType.WARNING);
      icon?.setBubbleVisible?.(true);
      this.workspace.centerOnBlock?.(blockId);
      Blockly.common.setSelected(block);
    }
    this._finish(rt, t('run.error.stopped'));
  }

  _finish(rt, text) {
    rt.stop();
    if (this.rt === rt) {
      this.rt = null;
      this.heldAt = null;
      this.pendingStep = false;
      this.workspace.highlightBlock(null);
      this._setState('idle');
      this.console.info(text);
    }
  }

  stop() {
    if (this.starting) {
      this.starting = 0;
      this._setState('idle');
      this.console.info(t('run.stopped'));
      return;
    }
    const rt = this.rt;
    if (!rt) return;
    this._finish(rt, t('run.stopped'));
  }

  pause() {
    if (!this.rt) return;
    const already = this.rt.paused && !this.rt.stepping;
    this.rt.pause();
    this._setState('paused');
    if (!already) this.console.info(t('run.paused'));
  }

  resume() {
    if (!this.rt) return;
    this.heldAt = null;
    this.rt.resume();
    this._setState('running');
    this.console.info(t('run.resumed', { run: this.runs }));
  }

  // Runs the highlighted block to its end (a move, a wait), then holds before the next one
  // with the robot stopped; the first Step starts a run and runs its first block.
  step() {
    if (!this.rt) { if (!this.starting) this.run({ step: true }); return; }
    const block = this.heldAt ? this.workspace.getBlockById(this.heldAt) : null;
    this.console.info(block ? t('run.step.block', { block: blockText(block) }) : t('run.step'));
    this.heldAt = null;
    this.rt.stepOnce();
    this._setState('paused');
  }
}

// A block's words, short enough for one console line.
function blockText(block) {
  const text = block.toString(40).replace(/\s+/g, ' ').trim();
  return text.length > 60 ? `${text.slice(0, 59)}…` : text;
}
