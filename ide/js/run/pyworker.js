// The Python worker (started by pyrun.js): Pyodide from vendor/pyodide/, the roslibpy of the page
// (runtime/browser/roslibpy.py) and the runtime the generated programs use. It checks programs'
// syntax while idle and runs one program, then ends: a fresh worker runs the next.
import { loadPyodide, version } from '../../vendor/pyodide/pyodide.mjs';

const RCLPY = ['__init__', '_engine', 'callback_groups', 'client', 'clock', 'context', 'duration', 'exceptions',
  'executors', 'logging', 'node', 'parameter', 'publisher', 'qos', 'service', 'signals', 'subscription', 'task',
  'time', 'timer', 'utilities', 'action/__init__', 'action/client', 'action/server'];
const FILES = {   // module file -> URL, put on Python's path (imported only when a program imports them)
  'roslibpy.py': '../../runtime/browser/roslibpy.py',
  'rosgate_browser.py': '../../runtime/browser/rosgate_browser.py',
  'rosgate_interfaces.py': '../../runtime/browser/rosgate_interfaces.py',
  'rosgate_runtime.py': '../../runtime/rosgate_runtime.py',
  ...Object.fromEntries(RCLPY.map((m) => [`rclpy/${m}.py`, `../../runtime/browser/rclpy/${m}.py`])),
};
const SEQ = 0, LOCK = 1, USED = 2, LINE = 3, HEAD = 16;
const MODULES = '/home/pyodide/rosgate';

let pyodide;
let ctrl;
let bytes;

const post = (m) => postMessage(m);

// What Python calls (rosgate_browser._js): ops out, the mailbox in, the running line.
const bridge = {
  send(json) { post({ kind: 'op', json }); },   // the page parses it: one parse, not two
  log(text, level) { post({ kind: 'log', text, level }); },
  close() { post({ kind: 'close' }); },
  line(n) { Atomics.store(ctrl, LINE, n); },
  // The worker's memory (tests/bench/pyodide.py: `import _rosgate_js; _rosgate_js.memory()`): Python's
  // wasm heap and the worker's JavaScript heap, bytes.
  memory() {
    return JSON.stringify({ wasm: pyodide?._module?.HEAPU8?.byteLength ?? null, js: performance.memory?.usedJSHeapSize ?? null });
  },
  // Waits up to `ms` for the gateway's messages and takes them all: '' or newline-separated JSON.
  take(ms) {
    if (ms > 0 && Atomics.load(ctrl, USED) === 0) {
      const seq = Atomics.load(ctrl, SEQ);
      if (Atomics.load(ctrl, USED) === 0) Atomics.wait(ctrl, SEQ, seq, ms);
    }
    if (Atomics.load(ctrl, USED) === 0) return '';
    while (Atomics.compareExchange(ctrl, LOCK, 0, 1) !== 0) { /* the page appends: microseconds */ }
    const used = Atomics.load(ctrl, USED);
    const copy = bytes.slice(0, used);
    Atomics.store(ctrl, USED, 0);
    Atomics.store(ctrl, LOCK, 0);
    post({ kind: 'taken' });
    return new TextDecoder().decode(copy);
  },
};

// The start's phases (ms from the worker's start), for `python -m tests.bench pyodide`.
const timing = {};

async function start() {
  const base = new URL(`../../vendor/pyodide/${version}/`, import.meta.url).href;   // immutable: from the cache
  // our modules come while Pyodide compiles (they are small; the cache revalidates them)
  const files = Promise.all(Object.entries(FILES).map(async ([name, url]) => {
    const r = await fetch(new URL(url, import.meta.url));
    if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
    return [name, await r.text()];
  }));
  pyodide = await loadPyodide({ indexURL: base, stdout: () => {}, stderr: () => {} });
  timing.pyodide = performance.now();
  pyodide.FS.mkdirTree(`${MODULES}/rclpy/action`);
  for (const [name, text] of await files) pyodide.FS.writeFile(`${MODULES}/${name}`, text);
  timing.files = performance.now();
  pyodide.runPython(`import sys; sys.path.insert(0, ${JSON.stringify(MODULES)})`);
  pyodide.registerJsModule('_rosgate_js', bridge);
  pyodide.setStdout({ batched: (text) => bridge.log(text, 'info') });
  pyodide.setStderr({ batched: (text) => bridge.log(text, 'error') });
  pyodide.pyimport('rosgate_browser');
  timing.ready = performance.now();
  // bytes that came over the network for Pyodide's files (0: from the browser's cache)
  timing.transferred = Object.fromEntries(performance.getEntriesByType('resource')
    .filter((r) => r.name.includes('/vendor/pyodide/')).map((r) => [r.name.split('/').pop(), r.transferSize]));
}

onmessage = (e) => {
  const d = e.data;
  if (d.kind === 'check') {
    const errors = pyodide.pyimport('rosgate_browser').check(d.source).toJs({ dict_converter: Object.fromEntries });
    post({ kind: 'checked', id: d.id, errors });
  } else if (d.kind === 'run') {
    ctrl = new Int32Array(d.sab, 0, 4);
    bytes = new Uint8Array(d.sab, HEAD);
    run(d);
  }
};

// Loads the Pyodide packages the program imports (only those: numpy when it says `import numpy`,
// from vendor/pyodide/VERSION/ where the gateway serves its wheel), then runs it.
async function run(d) {
  const missing = [];
  try {
    await pyodide.loadPackagesFromImports(d.source, {
      messageCallback: () => {},
      errorCallback: (text) => missing.push(text),
    });
  } catch (e) {
    missing.push(String(e?.message ?? e));
  }
  if (missing.length) {
    const names = [...new Set(missing.join(' ').match(/(?<=loading )[\w.-]+/g) ?? [])];
    const message = names.length
      ? `ImportError: the page has no ${names.join(', ')}: the gateway serves Python's standard library, the ROS `
        + `modules and only the Pyodide packages installed with it (${missing.join(' ').trim()})`
      : `ImportError: ${missing.join(' ')}`;
    post({ kind: 'error', line: null, message, traceback: message });
    post({ kind: 'done' });
    return;
  }
  const browser = pyodide.pyimport('rosgate_browser');
  const error = browser.run(d.source, d.namespace, d.base, pyodide.toPy(d.args ?? []));
  if (error) post({ kind: 'error', ...error.toJs({ dict_converter: Object.fromEntries }) });
  post({ kind: 'done' });
}

start().then(() => post({ kind: 'ready', timing }), (e) => post({ kind: 'failed', message: String(e?.message ?? e) }));
