// Python in the page: Pyodide in a Web Worker, over the page's own rosbridge connection.
//
// The worker's Python blocks as a script does (time.sleep, waiting for a message, a service
// call, an action's result): its ops come here by postMessage and go out on the page's `Ros`;
// what the gateway answers for them is written into a SharedArrayBuffer the worker waits on
// with Atomics.wait (a blocked worker cannot take postMessage events). That needs a
// cross-origin isolated page (the gateway sends COOP/COEP with the IDE's files).
//
// Stop terminates the worker (a `while True: pass` ends too, at once) and this side zeroes the
// robot as a block program's Stop does: a zero command on every velocity topic the program drove,
// its goals cancelled, its subscriptions and advertisements ended. A fresh worker is made for
// the next run as soon as one ends (Pyodide's files come from the browser's cache then), so Run
// after Stop does not wait for Pyodide to start.
import { isVelocityType, zeroVelocity } from '../../runtime/util.js';
import { t, num } from '../i18n.js';
import { heavy } from '../link/link.js';

const MAILBOX = 4 * 2 ** 20;     // bytes of gateway messages waiting for the worker
const PER_TOPIC = 200;           // messages of one topic kept while the worker is busy (the oldest go)
const LINE_EVERY = 50;           // ms between looks at the running line
const ID_SPAN = 1e9;             // ids of a run's ops: op:name:N with base <= N < base + ID_SPAN

let spare = null;                // an idle worker with Pyodide loaded: the next run's, and checkPython's
let current = null;              // the running program
let runs = 0;
let checks = 0;
const driven = new Map();        // velocity topic -> type, of every Python run of this page

addEventListener('pagehide', () => stopPython());   // a closed page stops its robot, as block programs do

// Control words of the shared buffer (Int32): 0 a counter bumped on every write (the worker waits
// on it), 1 the lock, 2 bytes used, 3 the running line. The bytes follow, newline-separated JSON.
const SEQ = 0, LOCK = 1, USED = 2, LINE = 3, HEAD = 16;

let lastTiming = null;   // the last worker's start: {pyodide, files, ready} ms in the worker, since: ms here

/** The phases of the last Python worker's start (tests/bench/pyodide.py), or null. */
export function startTiming() { return lastTiming; }

// guest: a program from another person's share link, in a worker the gateway serves with a policy
// that lets it reach nothing but Pyodide's and the runtime's files (js/run/foreign.js)
function startWorker(guest = false) {
  const made = performance.now();
  const worker = new Worker(new URL(guest ? './pyworker.js?guest=1' : './pyworker.js', import.meta.url), { type: 'module' });
  const ready = new Promise((resolve, reject) => {
    const onMessage = (e) => {
      if (e.data?.kind === 'ready') {
        worker.removeEventListener('message', onMessage);
        lastTiming = { ...e.data.timing, since: performance.now() - made };
        resolve(worker);
      }
      if (e.data?.kind === 'failed') { worker.removeEventListener('message', onMessage); reject(new Error(e.data.message)); }
    };
    worker.addEventListener('message', onMessage);
    worker.addEventListener('error', (e) => reject(new Error(e.message || 'the Python worker did not start')));
  });
  const w = { worker, ready, isReady: false };
  ready.then(() => { w.isReady = true; }, () => {});
  heavy(ready);   // Pyodide compiling takes the machine for seconds: the page's links are patient meanwhile
  return w;
}

function takeSpare() {
  const w = spare ?? startWorker();
  spare = null;
  return w;
}

/**
 * Starts the Python worker ahead of the first run (a text program in Python opened): Pyodide
 * loads while the student reads and types, not after Run. Resolves true once it is ready (false
 * when it could not start); a later runPython or checkPython takes that worker.
 */
export function prepare() {
  if (!globalThis.crossOriginIsolated) return Promise.resolve(false);   // it could not run here (runPython says why)
  if (!spare) spare = startWorker();
  return spare.ready.then(() => true, () => false);
}

/** Whether a worker with Pyodide loaded waits for the next run. */
export function isReady() { return Boolean(spare?.isReady); }

/** Python's own syntax check: [{line, col, message}] (line and col from 1), [] when it compiles. */
export async function checkPython(source) {
  if (!spare) spare = startWorker();
  const w = spare;
  let worker;
  try { worker = await w.ready; } catch (e) {
    if (spare === w) spare = null;
    return [{ line: 1, col: 1, message: t('py.no.start', { error: e.message }) }];
  }
  const id = ++checks;
  return new Promise((resolve) => {
    const done = (errors) => {
      worker.removeEventListener('message', onMessage);
      worker.removeEventListener('error', onError);
      resolve(errors);
    };
    const onMessage = (e) => { if (e.data?.kind === 'checked' && e.data.id === id) done(e.data.errors); };
    // a worker that failed meanwhile answers nothing: the run goes on and says why it cannot start
    const onError = () => { if (spare === w) spare = null; worker.terminate(); done([]); };
    worker.addEventListener('message', onMessage);
    worker.addEventListener('error', onError);
    worker.postMessage({ kind: 'check', id, source: String(source) });
  });
}

/**
 * Runs a Python program in a worker. Resolves when it ends (finished, failed or stopped); never
 * rejects. hooks: log(text, level) for print (level 'info') and stderr / tracebacks ('error'),
 * onLine(lineNo) for the running line of the program, onError({line, message, traceback}) with
 * the program's own line numbers (the traceback keeps only the program's frames; it reaches log too).
 * starting(ready, guest) is given the worker's readiness (a guest's worker loads Pyodide afresh:
 * the page's link allows the longer silence meanwhile).
 */
export async function runPython(source, { ros, namespace = '', args = [], log = () => {}, onLine = null, onError = () => {}, guest = false, starting = () => {} } = {}) {
  stopPython();
  const run = ++runs;
  const say = (text, level = 'info') => { try { log(text, level); } catch { /* the page's problem */ } };
  const fail = (message) => {
    say(message, 'error');
    try { onError({ line: null, message, traceback: '' }); } catch { /* the page's problem */ }
  };
  if (!ros?.isConnected) { fail(t('py.not.connected')); return; }
  if (!globalThis.crossOriginIsolated) {
    fail(t('py.not.isolated'));
    return;
  }
  const prog = new Program(run, ros, { log: say, onLine, onError });
  current = prog;
  const w = guest ? startWorker(true) : takeSpare();
  prog.worker = w.worker;
  try { starting(w.ready, guest); } catch { /* the page's problem */ }   // a guest's worker loads Pyodide afresh
  try {
    await Promise.race([w.ready, prog.ended]);
  } catch (e) {
    w.worker.terminate();
    if (current === prog) { current = null; fail(t('py.no.start', { error: e.message })); prog.end(); }
    return;
  }
  if (current !== prog) return prog.ended;          // stopped while Pyodide was loading
  prog.start(source, namespace, args);
  return prog.ended;
}

/** Ends the running Python program at once and zeroes the robot; runPython's promise resolves. */
export function stopPython() {
  const prog = current;
  if (!prog) return;
  current = null;
  prog.worker?.terminate();
  prog.end();
}

/** A zero command on every velocity topic a Python program of this page drove (what a block
 *  program's Stop publishes for its own); stopPython and the end of a run do it already. */
export function zeroRobot(ros) {
  if (!ros?.isConnected) return;
  for (const [topic, type] of driven) ros.callOnConnection({ op: 'publish', topic, msg: zeroVelocity(type) });
}

class Program {
  constructor(run, ros, hooks) {
    this.run = run;
    this.ros = ros;
    this.hooks = hooks;
    this.base = (Math.floor(Math.random() * 4e6) + 1) * ID_SPAN;   // unlike any roslib id of the page
    this.sab = new SharedArrayBuffer(HEAD + MAILBOX);
    this.ctrl = new Int32Array(this.sab, 0, 4);
    this.bytes = new Uint8Array(this.sab, HEAD);
    this.queue = [];              // encoded messages not yet in the mailbox
    this.topics = new Map();      // subscribed topic -> set of subscription ids
    this.advertised = new Map();  // topic -> type
    this.services = new Set();    // services the program serves (advertise_service)
    this.actions = new Set();     // actions the program serves (advertise_action)
    this.velocity = new Map();    // topic -> type, published velocity topics
    this.goals = new Map();       // goal id -> action, while waiting for the result
    this.encoder = new TextEncoder();
    this.ended = new Promise((resolve) => { this._resolve = resolve; });
    this.done = false;
    this.onRaw = (m) => this.heard(m);
    this.onClose = () => {
      if (current !== this) return;
      this.hooks.log(t('py.closed'), 'error');
      stopPython();
    };
  }

  start(source, namespace, args = []) {
    this.ros.transport?.on('message', this.onRaw);
    this.ros.on('close', this.onClose);
    this.worker.addEventListener('message', (e) => this.fromWorker(e.data));
    this.worker.addEventListener('error', (e) => {
      this.hooks.log(t('py.worker', { error: e.message }), 'error');
      if (current === this) stopPython();
    });
    if (this.hooks.onLine) {
      let last = 0;
      this.ticker = setInterval(() => {
        const line = Atomics.load(this.ctrl, LINE);
        if (line !== last && line > 0) { last = line; this.hooks.onLine(line); }
      }, LINE_EVERY);
    }
    this.worker.postMessage({ kind: 'run', source: String(source), namespace, args: args.map(String), sab: this.sab, base: this.base });
  }

  mine(id) {
    const n = Number(/:(\d+)$/.exec(String(id ?? ''))?.[1]);
    return n >= this.base && n < this.base + ID_SPAN;
  }

  // A frame from the gateway: the program's own replies, messages of its topics, and status
  // messages that name one of its ops (or none).
  heard(m) {
    if (this.done || !m || typeof m !== 'object') return;
    let keep = false;
    if (m.op === 'publish') keep = this.topics.has(m.topic);
    else if (m.op === 'call_service') keep = this.services.has(m.service);     // a call of a service it serves
    else if (m.op === 'send_action_goal' || m.op === 'cancel_action_goal') keep = this.actions.has(m.action);
    else if (m.op === 'status') keep = m.id === undefined || m.id === null || this.mine(m.id);
    else if (m.op === 'service_response' || m.op === 'action_feedback' || m.op === 'action_result') keep = this.mine(m.id);
    if (!keep) return;
    if (m.op === 'action_result') this.goals.delete(m.id);
    this.deliver(m);
  }

  deliver(m) {
    const data = this.encoder.encode(`${JSON.stringify(m)}\n`);
    if (data.length > MAILBOX) {
      const msg = t('py.mailbox', { op: m.op, bytes: num(data.length), max: num(MAILBOX) });
      this.deliver({ op: 'status', level: 'error', id: m.id, msg });
      return;
    }
    if (m.op === 'publish') {
      const same = this.queue.filter((q) => q.topic === m.topic);
      if (same.length >= PER_TOPIC) this.queue.splice(this.queue.indexOf(same[0]), 1);
    }
    this.queue.push({ topic: m.op === 'publish' ? m.topic : null, data });
    this.flush();
  }

  // Moves what fits into the mailbox; the rest waits for the worker to take what is there.
  flush() {
    if (!this.queue.length || this.done) return;
    // the worker holds the lock while it copies out (microseconds); a worker that died holding it
    // must not hang the page: look again a little later
    let tries = 0;
    while (Atomics.compareExchange(this.ctrl, LOCK, 0, 1) !== 0) {
      if (++tries > 100000) { setTimeout(() => this.flush(), 5); return; }
    }
    let used = Atomics.load(this.ctrl, USED);
    let n = 0;
    while (n < this.queue.length && used + this.queue[n].data.length <= MAILBOX) {
      this.bytes.set(this.queue[n].data, used);
      used += this.queue[n].data.length;
      n += 1;
    }
    Atomics.store(this.ctrl, USED, used);
    Atomics.store(this.ctrl, LOCK, 0);
    if (n) {
      this.queue.splice(0, n);
      Atomics.add(this.ctrl, SEQ, 1);
      Atomics.notify(this.ctrl, SEQ);
    }
  }

  fromWorker(d) {
    if (this.done || !d) return;
    if (d.kind === 'op') this.send(JSON.parse(d.json));
    else if (d.kind === 'taken') this.flush();
    else if (d.kind === 'log') this.hooks.log(d.text, d.level);
    else if (d.kind === 'error') {
      if (d.traceback) this.hooks.log(d.traceback, 'error');
      try {
        this.hooks.onError({ line: d.line ?? null, message: d.message, traceback: d.traceback });
      } catch { /* the page's problem */ }
    } else if (d.kind === 'close') this.cleanup();
    else if (d.kind === 'done') {
      if (current === this) current = null;
      this.worker.terminate();
      this.end();
    }
  }

  // An op of the program, on the page's connection; what it starts is remembered for the end.
  send(msg) {
    if (!msg || typeof msg !== 'object') return;
    if (!this.ros.isConnected) {       // the page's link dropped this connection: nothing would arrive
      if (current === this) { this.hooks.log(t('py.closed'), 'error'); stopPython(); }
      return;
    }
    const { op, topic } = msg;
    if (op === 'subscribe') {
      if (!this.topics.has(topic)) this.topics.set(topic, new Set());
      this.topics.get(topic).add(msg.id);
    } else if (op === 'unsubscribe') {
      const ids = this.topics.get(topic);
      ids?.delete(msg.id);
      if (ids && !ids.size) this.topics.delete(topic);
    } else if (op === 'advertise') {
      this.advertised.set(topic, msg.type);
    } else if (op === 'unadvertise') {
      this.advertised.delete(topic);
    } else if (op === 'advertise_service') {
      this.services.add(msg.service);
    } else if (op === 'unadvertise_service') {
      this.services.delete(msg.service);
    } else if (op === 'advertise_action') {
      this.actions.add(msg.action);
    } else if (op === 'unadvertise_action') {
      this.actions.delete(msg.action);
    } else if (op === 'publish') {
      const type = this.advertised.get(topic);
      if (type && isVelocityType(type)) { this.velocity.set(topic, type); driven.set(topic, type); }
    } else if (op === 'send_action_goal') {
      this.goals.set(msg.id, msg.action);
    } else if (op === 'cancel_action_goal') {
      this.goals.delete(msg.id);
    }
    this.ros.callOnConnection(msg);
  }

  // What a block program's Stop does (Runtime.stop): zero every velocity topic the program
  // drove, cancel its goals, end its subscriptions and advertisements.
  cleanup() {
    const send = (m) => { if (this.ros.isConnected) this.ros.callOnConnection(m); };
    for (const [topic, type] of this.velocity) send({ op: 'publish', topic, msg: zeroVelocity(type) });
    for (const [id, action] of this.goals) send({ op: 'cancel_action_goal', id, action });
    for (const [topic, ids] of this.topics) for (const id of ids) send({ op: 'unsubscribe', id, topic });
    for (const topic of this.advertised.keys()) send({ op: 'unadvertise', topic });
    for (const service of this.services) send({ op: 'unadvertise_service', service });
    for (const action of this.actions) send({ op: 'unadvertise_action', action });
    this.goals.clear();
    this.topics.clear();
    this.advertised.clear();
    this.services.clear();
    this.actions.clear();
  }

  end() {
    if (this.done) return;
    this.cleanup();
    this.done = true;
    clearInterval(this.ticker);
    this.ros.transport?.off?.('message', this.onRaw);
    this.ros.off('close', this.onClose);
    this.queue = [];
    this._resolve();
    // the next run starts at once, without Pyodide's start in its way (its files are in the cache)
    if (!spare) spare = startWorker();
  }
}
