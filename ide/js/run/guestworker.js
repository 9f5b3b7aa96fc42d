// A JavaScript text program from another person's share link, run in a worker of its own (js/run/foreign.js).
// The gateway serves this file with a policy that lets it load roslib and the runtime and nothing
// else: no fetch, no XMLHttpRequest, no websocket, no import() of a page or an API
// (gateway/web/pages.py GUEST_WORKERS); what the policy would refuse is also taken away below. Its
// one way out is the page: a roslib Ros whose transport is the worker's messages, so the page's door
// sees every op (and zeroes what it drove at the end) and hands back what is the program's.
// The program sees what a text program in the page sees: ros, ROSLIB, the runtime (`import { rt }
// from 'rosgate'`, prepared by the page), console and timers; its running line and errors are told
// to the page by line number.
import * as ROSLIB from '../../vendor/roslib.mjs';
import { Runtime, StopSignal, fmt, field, pick, yaw, rangeAt } from '../../runtime/runtime.js';
import { angleDiff } from '../../runtime/util.js';

for (const name of ['fetch', 'XMLHttpRequest', 'WebSocket', 'EventSource', 'WebTransport', 'Worker', 'SharedWorker',
  'importScripts', 'BroadcastChannel', 'indexedDB', 'caches']) {
  for (let o = self; o; o = Object.getPrototypeOf(o)) {
    try { if (Object.hasOwn(o, name)) delete o[name]; } catch { /* not deletable: the policy refuses it */ }
  }
}

const AsyncFunction = Object.getPrototypeOf(async () => {}).constructor;
const PARAMS = ['ros', 'ROSLIB', '__modules', 'console', 'setTimeout', 'setInterval', 'clearTimeout', 'clearInterval'];
const say = (msg) => postMessage(msg);

class PageTransport extends ROSLIB.AbstractTransport {
  constructor() { super(); this.open = false; }
  send(msg) { say({ kind: 'op', op: msg }); }
  close() { this.open = false; this.emit('close', {}); }
  isConnecting() { return false; }
  isOpen() { return this.open; }
  isClosing() { return false; }
  isClosed() { return !this.open; }
}

const transport = new PageTransport();
const ros = new ROSLIB.Ros({ transportFactory: async () => transport });

// Lines the function constructor puts ahead of the body (as js/run/textrun.js counts them).
let headerLines = null;
function header() {
  if (headerLines === null) {
    let stack = '';
    try { new Function(...PARAMS, 'throw new Error()\n//# sourceURL=rosgate-probe.js')(); } catch (e) { stack = e.stack ?? ''; }
    const m = /rosgate-probe\.js:(\d+):/.exec(stack);
    headerLines = m ? Number(m[1]) - 1 : 2;
  }
  return headerLines;
}

function lineOf(stack, url) {
  const m = new RegExp(`${url.replace(/[.]/g, '\\.')}:(\\d+):\\d+`).exec(stack ?? '');
  return m ? Number(m[1]) - header() : null;
}

const show = (v) => (typeof v === 'string' ? v : fmt(v));

async function run({ code, url, namespace }) {
  await ros.connect('page');
  transport.open = true;
  transport.emit('open', {});
  const here = () => { const line = lineOf(new Error().stack, url); if (line) say({ kind: 'line', line }); };
  const fail = (e) => {
    if (e instanceof StopSignal) return;
    say({ kind: 'error', line: lineOf(e?.stack, url), message: e?.message ?? String(e), name: e?.name ?? '' });
  };
  let fn;
  try { fn = new AsyncFunction(...PARAMS, `${code}\n//# sourceURL=${url}`); } catch (e) { fail(e); return; }
  const rt = new Runtime(ros, { log: (text, level) => say({ kind: 'log', text, level }), highlight: () => {}, error: fail },
    { namespace });
  const rtView = new Proxy(rt, {
    get: (target, key) => {
      const v = target[key];
      if (typeof v !== 'function' || key === 'constructor') return v;
      return (...args) => { here(); return v.apply(target, args); };
    },
  });
  const printer = (level) => (...args) => { here(); say({ kind: 'log', text: args.map(show).join(' '), level }); };
  const console_ = { log: printer('log'), info: printer('log'), debug: printer('log'), warn: printer('log'), error: printer('error') };
  const timers = new Set();
  const guard = (f) => (...a) => { try { return typeof f === 'function' ? f(...a) : undefined; } catch (e) { fail(e); return undefined; } };
  const timer = (set, repeat) => (f, ms, ...a) => {
    const id = set(() => { if (!repeat) timers.delete(id); guard(f)(...a); }, ms);
    timers.add(id);
    return id;
  };
  const clearer = (clear) => (id) => { timers.delete(id); clear(id); };
  const modules = { rosgate: { rt: rtView, fmt, field, pick, yaw, rangeAt, angleDiff, StopSignal }, roslib: ROSLIB };
  try {
    await fn(ros, ROSLIB, modules, console_, timer(setTimeout, false), timer(setInterval, true),
      clearer(clearTimeout), clearer(clearInterval));
  } catch (e) { fail(e); return; }
  const handlers = [...rt.subs.values()].some((s) => s.handlers.length);
  if (handlers || timers.size) { say({ kind: 'callbacks' }); return; }
  await rt.settle();
  say({ kind: 'done' });
}

self.addEventListener('unhandledrejection', (e) => say({ kind: 'error', line: null, message: String(e.reason?.message ?? e.reason) }));
self.onmessage = (e) => {
  const d = e.data ?? {};
  if (d.kind === 'frame') transport.handleRawMessage(d.msg);
  else if (d.kind === 'run') run(d).catch((err) => say({ kind: 'error', line: null, message: String(err?.message ?? err) }));
};
