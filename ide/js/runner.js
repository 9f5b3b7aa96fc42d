// Runs the workspace's JavaScript live: Run, Pause, Step, Stop, highlighting, and
// errors shown on the block that raised them.
/* global Blockly */
import { Runtime, StopSignal } from '../runtime/runtime.js';
import { gen as jsGen } from '../generators/javascript.js';

const AsyncFunction = Object.getPrototypeOf(async () => {}).constructor;

export class Runner extends EventTarget {
  constructor(workspace, getRos, console_, getNamespace = () => '') {
    super();
    this.workspace = workspace;
    this.getRos = getRos;
    this.getNamespace = getNamespace;
    this.console = console_;
    this.rt = null;
    this.state = 'idle';         // idle | running | paused
    this.errors = new Map();     // block id -> message
    this.runs = 0;
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

  async run({ paused = false } = {}) {
    if (this.rt) this.stop();
    const ros = this.getRos();
    if (!ros?.isConnected) {
      this.console.error('Not connected to the gateway: press Reconnect.');
      return;
    }
    this.clearErrors();
    let code;
    try {
      code = jsGen.generate(this.workspace, { instrument: true });
    } catch (e) {
      this.console.error(`Cannot generate code: ${e.message}`);
      return;
    }
    const run = ++this.runs;
    const rt = new Runtime(ros, {
      log: (text, level) => this.console.log(text, level),
      highlight: (id) => { if (this.rt === rt) this.workspace.highlightBlock(id); },
      error: (e, id) => this._error(rt, e, id),
      held: (id) => { if (this.rt === rt) { this.heldAt = id; this.dispatchEvent(new CustomEvent('held', { detail: id })); } },
    }, { namespace: this.getNamespace() });
    this.rt = rt;
    if (paused) rt.pause();
    this._setState(paused ? 'paused' : 'running');
    this.console.info(`▶ run ${run}`);
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
      if (rt.subs.size && [...rt.subs.values()].some((s) => s.handlers.length)) {
        this.console.info('main blocks done; message handlers keep running until Stop');
        return;
      }
      this._finish(rt, `■ run ${run} finished`);
    } catch (e) {
      if (e instanceof StopSignal) return;
      this._error(rt, e, rt.current);
    }
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
    this._finish(rt, '■ stopped after an error (robot stopped)');
  }

  _finish(rt, text) {
    rt.stop();
    if (this.rt === rt) {
      this.rt = null;
      this.heldAt = null;
      this.workspace.highlightBlock(null);
      this._setState('idle');
      this.console.info(text);
    }
  }

  stop() {
    const rt = this.rt;
    if (!rt) return;
    this._finish(rt, '■ stopped (robot stopped)');
  }

  pause() {
    if (!this.rt) return;
    this.rt.pause();
    this._setState('paused');
  }

  resume() {
    if (!this.rt) return;
    this.heldAt = null;
    this.rt.resume();
    this._setState('running');
  }

  // Runs the highlighted block to its end (a move, a wait), then holds before the next one
  // with the robot stopped; the first Step starts a paused run.
  step() {
    if (!this.rt) { this.run({ paused: true }); return; }
    this.heldAt = null;
    this.rt.stepOnce();
    this._setState('paused');
  }
}
