// Runs a text program in the page, with the Run and Stop the block programs use and their console.
//
// JavaScript: the text is the body of an async function (top-level `await`), with `ros` (the
// page's connected Ros), `ROSLIB` (roslib's classes) and the runtime (`import { rt } from
// 'rosgate'`) in scope; `import … from 'rosgate' | 'roslib'` lines become constants on the same
// line, so the student's line numbers hold. The running line is the line of the program's
// newest call into the runtime, roslib or the console, read from the call's stack.
// Python: js/run/pyrun.js (Pyodide in a worker), imported the first time a Python program runs.
//
// Both go through one door (RunDoor): the program's ros is the page's behind a gate that
// notes the velocity topics it publishes to and what it subscribes; Stop (or an error) shuts
// the gate first — nothing the program sends afterwards leaves the page — then publishes a zero
// command on each velocity topic it drove, as a block program's Stop does.
import * as ROSLIB from 'roslib';
import { Runtime, StopSignal, fmt, field, pick, yaw, rangeAt } from '../../runtime/runtime.js';
import { isVelocityType, zeroVelocity, angleDiff } from '../../runtime/util.js';
import { t, num } from '../i18n.js';

const AsyncFunction = Object.getPrototypeOf(async () => {}).constructor;
const PARAMS = ['ros', 'ROSLIB', '__modules', 'console', 'setTimeout', 'setInterval', 'clearTimeout', 'clearInterval'];

// ---- the door ----------------------------------------------------------------
export class RunDoor {
  constructor(ros) {
    this.real = ros;
    this.open = true;
    this.types = new Map();       // topic -> type advertised through the door
    this.velocity = new Map();    // velocity topics published to -> type
    this.subscribed = new Map();  // subscribe id -> topic
    this.onSend = null;           // (msg) => void: the run notes its line
    const send = (msg) => this._send(msg);
    this.ros = new Proxy(ros, {
      get(target, key) {
        if (key === 'callOnConnection') return send;
        const v = target[key];
        return typeof v === 'function' ? v.bind(target) : v;
      },
    });
  }

  _send(msg) {
    if (!this.open || !msg) return;
    if (msg.op === 'advertise') this.types.set(msg.topic, msg.type);
    else if (msg.op === 'publish' && isVelocityType(this.types.get(msg.topic))) this.velocity.set(msg.topic, this.types.get(msg.topic));
    else if (msg.op === 'subscribe') this.subscribed.set(msg.id, msg.topic);
    else if (msg.op === 'unsubscribe') this.subscribed.delete(msg.id);
    this.onSend?.(msg);
    this.real.callOnConnection(msg);
  }

  // Nothing more from the program; the robot stopped; its subscriptions ended.
  close() {
    if (!this.open) return;
    this.open = false;
    for (const [topic, type] of this.velocity) this.real.callOnConnection({ op: 'publish', topic, msg: zeroVelocity(type) });
    for (const [id, topic] of this.subscribed) this.real.callOnConnection({ op: 'unsubscribe', id, topic });
    this.subscribed.clear();
    for (const topic of this.types.keys()) this.real.callOnConnection({ op: 'unadvertise', topic });
    this.types.clear();
  }
}

// ---- JavaScript text -------------------------------------------------------------
export class ProgramError extends Error {
  constructor(line, message) { super(message); this.line = line; }
}

const IMPORT = /^(\s*)import\s+(.+?)\s+from\s+(['"])([^'"]+)\3\s*;?\s*$/;
const MODULES = ['rosgate', 'roslib'];

// `import` lines (one line each, from 'rosgate' or 'roslib') as constants on the same line.
export function prepareJs(text) {
  return text.split('\n').map((line, i) => {
    if (!/^\s*import\b(?!\s*\()/.test(line)) return line;
    const m = IMPORT.exec(line);
    if (!m || !MODULES.includes(m[4])) {
      throw new ProgramError(i + 1, t('text.import.only', { modules: MODULES.map((s) => `'${s}'`).join(', ') }));
    }
    const from = `__modules[${JSON.stringify(m[4])}]`;
    const clause = m[2].trim();
    let decl;
    if (/^\*\s+as\s+[\w$]+$/.test(clause)) decl = `const ${clause.split(/\s+/).pop()} = ${from};`;
    else if (/^\{[^}]*\}$/.test(clause)) decl = `const ${clause.replace(/\b([\w$]+)\s+as\s+([\w$]+)/g, '$1: $2')} = ${from};`;
    else if (/^[\w$]+$/.test(clause)) decl = `const ${clause} = ${from};`;
    else throw new ProgramError(i + 1, t('text.import.unread', { clause }));
    return m[1] + decl;
  }).join('\n');
}

let sourceCount = 0;
let headerLines = null;
// Lines the function constructor puts ahead of the body (2 in V8: `async function anonymous(…\n) {\n`).
function header() {
  if (headerLines === null) {
    const url = 'rosgate-probe.js';
    let stack = '';
    try { new Function(...PARAMS, `throw new Error()\n//# sourceURL=${url}`)(); } catch (e) { stack = e.stack ?? ''; }
    const m = new RegExp(`${url.replace('.', '\\.')}:(\\d+):`).exec(stack);
    headerLines = m ? Number(m[1]) - 1 : 2;
  }
  return headerLines;
}

const TRUNCATED = /end of input|Unterminated template|missing \) after|Unexpected end/i;

// Compiles the prepared text; a syntax error carries its line: the first prefix of the text that
// fails otherwise than by ending early (V8 gives the message of a body's syntax error, not its line).
export function compileJs(text, url) {
  const code = prepareJs(text);
  try {
    return new AsyncFunction(...PARAMS, `${code}\n//# sourceURL=${url}`);
  } catch (e) {
    if (!(e instanceof SyntaxError)) throw e;
    const lines = code.split('\n');
    let line = lines.length;
    for (let n = 1; n <= lines.length; n += 1) {
      try { new AsyncFunction(...PARAMS, lines.slice(0, n).join('\n')); } catch (err) {
        if (!TRUNCATED.test(err.message) || n === lines.length) { line = n; break; }
      }
    }
    throw new ProgramError(line, `SyntaxError: ${e.message}`);
  }
}

// The student's line of the innermost frame of the program in a stack.
export function lineOf(stack, url) {
  const m = new RegExp(`${url.replace(/[.]/g, '\\.')}:(\\d+):\\d+`).exec(stack ?? '');
  return m ? Number(m[1]) - header() : null;
}

function show(v) {
  return typeof v === 'string' ? v : fmt(v);
}

export class TextRunner extends EventTarget {
  // ide: { ros, ns, console, editor, graph }; ready(): resolves when the graph is read
  constructor(ide, { ready = async () => {} } = {}) {
    super();
    this.ide = ide;
    this.ready = ready;
    this.state = 'idle';
    this.runs = 0;
    this.run_ = null;          // the run in progress: {n, door, rt, url, timers, lang, py}
    this.line = null;
    addEventListener('pagehide', () => this.stop(t('text.why.page')));
    addEventListener('error', (e) => this._uncaught(e.error));
    addEventListener('unhandledrejection', (e) => this._uncaught(e.reason));
  }

  _setState(s) {
    this.state = s;
    this.dispatchEvent(new CustomEvent('state', { detail: s }));
  }

  // The line the run is at, shown in the editor (once per frame) and sent to the class view.
  _at(run, line) {
    if (this.run_ !== run || !line || line === this.line) return;
    this.line = line;
    if (!this._frame) {
      this._frame = requestAnimationFrame(() => {
        this._frame = null;
        if (this.run_ === run) this.ide.editor.running(this.line);
      });
    }
    this.dispatchEvent(new CustomEvent('line', { detail: line }));
  }

  _here(run) {
    if (run.lang === 'javascript') this._at(run, lineOf(new Error().stack, run.url));
  }

  async run(text, lang) {
    if (this.run_) this.stop();
    const ros = this.ide.ros;
    if (!ros?.isConnected) { this.ide.console.error(t('text.not.connected')); return; }
    const n = ++this.runs;
    this.ide.editor.error(null);
    this.ide.editor.running(null);
    this.line = null;
    const door = new RunDoor(ros);
    const run = { n, door, lang, url: `rosgate-program-${++sourceCount}.js`, timers: new Set(), rt: null };
    this.run_ = run;
    this._setState('running');
    this.ide.console.info(t('text.run.start', { n: num(n), lang: lang === 'python' ? 'Python' : 'JavaScript' }));
    try {
      if (lang === 'python') await this._python(run, text);
      else await this._javascript(run, text);
    } catch (e) {
      if (!(e instanceof StopSignal)) this._error(run, e);
    }
  }

  // ---- JavaScript ----
  async _javascript(run, text) {
    await this.ready();
    if (this.run_ !== run) return;
    if (this.ide.foreign) { await this._guest(run, text); return; }   // another person's: apart (js/run/foreign.js)
    const fn = compileJs(text, run.url);
    const door = run.door;
    const rt = new Runtime(door.ros, {
      log: (t, level) => this.ide.console.log(t, level),
      highlight: () => {},
      error: (e) => this._error(run, e),
    }, { namespace: this.ide.ns ?? '' });
    run.rt = rt;
    door.onSend = () => this._here(run);
    // the runtime's calls note the line they are called from
    const rtView = new Proxy(rt, {
      get: (target, key) => {
        const v = target[key];
        if (typeof v !== 'function' || key === 'constructor') return v;
        return (...args) => { this._here(run); return v.apply(target, args); };
      },
    });
    const printer = (level) => (...args) => {
      if (this.run_ !== run) return;
      this._here(run);
      const line = args.map(show).join(' ');
      if (level === 'error') this.ide.console.error(line); else this.ide.console.log(line, level);
    };
    const console_ = { log: printer('log'), info: printer('log'), debug: printer('log'), warn: printer('log'), error: printer('error') };
    const guard = (f) => (...a) => {
      if (this.run_ !== run) return undefined;
      try { return typeof f === 'function' ? f(...a) : undefined; } catch (e) { this._error(run, e); return undefined; }
    };
    const timer = (set, clear, repeat) => (f, ms, ...a) => {
      if (this.run_ !== run) return 0;
      const id = set(() => { if (!repeat) run.timers.delete(id); guard(f)(...a); }, ms);
      run.timers.add(id);
      run.clears = run.clears ?? new Map();
      run.clears.set(id, clear);
      return id;
    };
    const clearer = (clear) => (id) => { run.timers.delete(id); clear(id); };
    const modules = {
      rosgate: { rt: rtView, fmt, field, pick, yaw, rangeAt, angleDiff, StopSignal },
      roslib: ROSLIB,
    };
    await fn(door.ros, ROSLIB, modules, console_, timer(setTimeout, clearTimeout, false),
      timer(setInterval, clearInterval, true), clearer(clearTimeout), clearer(clearInterval));
    if (this.run_ !== run) return;
    const handlers = [...rt.subs.values()].some((s) => s.handlers.length);
    const own = new Set([...rt.subs.values()].map((s) => s.id));     // the runtime's, not the program's own
    const listening = [...door.subscribed.keys()].some((id) => !own.has(id));
    if (handlers || run.timers.size || listening) {
      this.ide.console.info(t('text.callbacks'));
      return;
    }
    await rt.settle();
    this._finish(run, t('text.finished', { n: num(run.n) }));
  }

  // A program from another person's share link: in a worker of its own, its ops through the door.
  async _guest(run, text) {
    compileJs(text, run.url);                    // its syntax errors, with their lines, here
    const { runGuest } = await import('./foreign.js');
    if (this.run_ !== run) return;
    run.guest = runGuest(prepareJs(text), {
      url: run.url, namespace: this.ide.ns ?? '', door: run.door, ros: this.ide.ros,
      log: (text, level) => { if (this.run_ === run) { if (level === 'error') this.ide.console.error(text); else this.ide.console.log(text, level); } },
      line: (n) => this._at(run, n),
      error: ({ line, message, name }) => this._error(run, new ProgramError(line, name && name !== 'Error' ? `${name}: ${message}` : message)),
      callbacks: () => { if (this.run_ === run) this.ide.console.info(t('text.callbacks')); },
    });
    await run.guest.ended;
    if (this.run_ === run) this._finish(run, t('text.finished', { n: num(run.n) }));
  }

  // ---- Python (js/run/pyrun.js: Pyodide in a worker, loaded at the first Python run) ----
  async _python(run, text) {
    let py;
    try {
      py = await import('./pyrun.js');
    } catch (e) {
      throw new Error(t('text.python.noload', { error: e.message }));
    }
    if (this.run_ !== run) return;
    run.py = py;
    if (!py.isReady()) {      // Python started loading when the program opened (textmode.js): say we wait
      this.ide.console.info(t('text.python.loading'));
      py.prepare();
    }
    run.phase = 'checking';           // where a Python run is: checking (Python's load, then its check), graph, running
    const problems = await py.checkPython(text);
    if (this.run_ !== run) return;
    if (problems.length) {
      const [first] = problems;
      for (const p of problems) this.ide.console.error(t('text.at.line', { line: num(p.line), message: p.message }));
      this.ide.editor.error(first.line, first.message);
      this._finish(run, t('text.not.run'));
      return;
    }
    run.phase = 'graph';
    await this.ready();
    if (this.run_ !== run) return;
    run.phase = 'running';
    await py.runPython(text, {
      guest: Boolean(this.ide.foreign),          // another person's program: a worker apart (js/run/foreign.js)
      starting: (ready, guest) => {              // its own Pyodide loads (the link is patient meanwhile: pyrun.js)
        if (guest && this.run_ === run) this.ide.console.info(t('text.python.loading'));
      },
      ros: run.door.ros,
      namespace: this.ide.ns ?? '',
      args: this.ide.textMode?.args ?? [],
      log: (t, level) => { if (this.run_ === run) this.ide.console.log(t, level); },
      onLine: (line) => this._at(run, line),
      onError: ({ line, message }) => {   // (its traceback has reached log already)
        if (this.run_ !== run) return;
        this._error(run, new ProgramError(line, message));
      },
    });
    if (this.run_ === run) this._finish(run, t('text.finished', { n: num(run.n) }));
  }

  // ---- the end ----
  _uncaught(err) {
    const run = this.run_;
    if (!run || run.lang !== 'javascript' || !err) return;
    if (lineOf(err.stack, run.url) !== null) this._error(run, err);
  }

  _error(run, e) {
    if (this.run_ !== run || e instanceof StopSignal) return;
    const line = e instanceof ProgramError ? e.line : (run.lang === 'javascript' ? lineOf(e?.stack, run.url) : null) ?? this.line;
    const name = e?.name && e.name !== 'Error' && !(e instanceof ProgramError) ? `${e.name}: ` : '';
    const msg = `${name}${e?.message ?? String(e)}`;
    this.ide.console.error(line ? t('text.at.line', { line: num(line), message: msg }) : msg);
    this.ide.editor.error(line, msg);
    this._finish(run, t('text.stopped.error'));
  }

  _finish(run, text) {
    if (this.run_ !== run) return;
    this.run_ = null;
    run.rt?.stop();                        // the runtime's waits end, its goals are cancelled, robot zeroed
    run.guest?.stop();                     // a foreign program's worker ends (its goals cancelled)
    // Python's worker ends first: pyrun's own cleanup (its goals cancelled, subscriptions and
    // advertisements ended, zero on what it drove) still passes the open door
    if (run.py) {
      try { run.py.stopPython(); } catch (e) { this.ide.console.error(t('text.python.stopping', { error: e.message })); }
    }
    run.door.close();                      // the program sends nothing more; zero on what it drove
    for (const id of run.timers) run.clears?.get(id)?.(id);
    run.timers.clear();
    this.ide.editor.running(null);
    this.line = null;
    this._setState('idle');
    this.ide.console.info(text);
  }

  // Ends the run; `why` says what ended it (the Stop button's run says "stopped").
  stop(why = null) {
    const run = this.run_;
    if (run) this._finish(run, why ? t('text.stopped.why', { why }) : t('text.stopped'));
  }
}
