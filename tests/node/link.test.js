// The pages' link helper (ide/js/link/link.js) against a real gateway: pings, a gateway that goes
// away and comes back, and the backoff's bounds.
import { after, test } from 'node:test';
import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import { once } from 'node:events';
import { fileURLToPath } from 'node:url';
import path from 'node:path';
import { Link, RETRY, SILENCE, backoff, heavy } from '../../ide/js/link/link.js';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..');
const python = process.env.ROSGATE_PYTHON || path.join(root, '.venv', 'bin', 'python');
const running = new Set();

async function startGateway(port = 0) {
  const proc = spawn(python, ['-m', 'gateway', '--port', String(port), '--address', '127.0.0.1', '--robot', 'none',
    '--programs-dir', path.join(root, '.venv', 'node-test-programs')], { cwd: root, stdio: ['ignore', 'pipe', 'inherit'] });
  running.add(proc);
  proc.on('exit', () => running.delete(proc));
  let line = '';
  for await (const chunk of proc.stdout) {
    line += chunk;
    if (line.includes('\n')) break;
  }
  proc.stdout.resume();
  return { proc, url: line.match(/websocket (ws:\/\/\S+)/)[1] };
}

after(() => { for (const p of running) p.kill('SIGKILL'); });

function event(target, name, ms, what) {
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`${what}: not within ${ms} ms`)), ms);
    target.addEventListener(name, (e) => { clearTimeout(timer); resolve(e); }, { once: true });
  });
}

test('backoff grows from RETRY.first to RETRY.cap, spread by the jitter', () => {
  const { first, cap, jitter } = RETRY;
  assert.equal(backoff(0, RETRY, () => 0.5), first);
  assert.equal(backoff(30, RETRY, () => 0.5), cap);
  assert.equal(backoff(30, RETRY, () => 0), cap * (1 - jitter));
  assert.ok(backoff(30, RETRY, () => 0.999999) < cap * (1 + jitter));
  assert.ok(cap * (1 + jitter) < 1100, 'an attempt starts within about a second of the link\'s return');
  const spread = new Set(Array.from({ length: 20 }, () => backoff(5)));
  assert.ok(spread.size > 10, 'pages do not knock at once');
});

test('the silence that counts as lost: SILENCE on a steady link, longer where the gateway is slow and uneven', () => {
  const link = new Link('ws://127.0.0.1:1/');
  assert.equal(link.silence(), SILENCE);                     // no round trip measured yet
  for (let i = 0; i < 40; i++) link._measured(150 + (i % 2 ? 50 : -50));   // a home link: 150 ± 50 ms
  assert.equal(link.silence(), SILENCE);
  for (const rtt of [900, 60, 1400, 80, 1100, 70]) link._measured(rtt);     // a busy gateway's answers
  const busy = link.silence();
  assert.ok(busy > 2000 && busy <= 5000, `busy: ${busy} ms`);
  for (let i = 0; i < 60; i++) link._measured(20);          // it recovers: back to SILENCE
  assert.equal(link.silence(), SILENCE);
  for (let i = 0; i < 20; i++) link._measured(i % 2 ? 20000 : 10);
  assert.equal(link.silence(), 5000);                        // capped
});

test('while the page is busy with a heavy load it knows of (patient), the link allows the longest silence', async () => {
  const link = new Link('ws://127.0.0.1:1/');
  for (let i = 0; i < 40; i++) link._measured(20);          // a quick link: SILENCE
  assert.equal(link.silence(), SILENCE);
  let done;
  const loading = new Promise((resolve) => { done = resolve; });
  const failing = Promise.reject(new Error('no Pyodide'));
  assert.equal(link.patient(loading), loading);
  link.patient(failing);
  assert.equal(link.silence(), 5000);                        // Pyodide compiling: pongs may come late
  await failing.catch(() => {});
  await new Promise((resolve) => { setTimeout(resolve, 0); });
  assert.equal(link.silence(), 5000, 'one heavy moment still under way');
  done();
  await loading;
  await new Promise((resolve) => { setTimeout(resolve, 0); });
  assert.equal(link.silence(), SILENCE);                     // settled (or failed): the usual limit
});

test('a link shows its round trip, and heals by itself when the gateway comes back', async () => {
  const first = await startGateway();
  const port = Number(new URL(first.url).port);
  const link = new Link(first.url);
  const opened = event(link, 'open', 10000, 'open');
  link.start();
  await opened;
  while (link.rtt === null) await new Promise((r) => setTimeout(r, 20));
  assert.ok(link.rtt >= 0 && link.rtt < 1000);
  assert.match(link.describe(), /^RTT \d+ ms/);

  const lost = event(link, 'lost', 5000, 'lost');
  first.proc.kill('SIGKILL');
  await lost;
  assert.equal(link.state, 'lost');
  await new Promise((r) => setTimeout(r, 1500));   // attempts fail meanwhile, backing off
  const again = await startGateway(port);
  const back = performance.now();
  await event(link, 'open', 5000, 'open again');
  const healed = performance.now() - back;
  assert.equal(link.state, 'connected');
  assert.ok(healed < 2000, `connected again ${healed.toFixed(0)} ms after the gateway came back`);
  link.restart();   // the ↻ button: a fresh connection
  await event(link, 'open', 5000, 'restart');
  link._drop();
  again.proc.kill('SIGKILL');
});

test('an idle robot\'s data is current: its age counts from the newest pong, not from the last message', async () => {
  const gw = await startGateway();
  const link = new Link(gw.url);
  const opened = event(link, 'open', 10000, 'open');
  link.start();
  const ros = (await opened).detail;
  // one latched message, then nothing: a robot at rest (turtlesim's markers change only when it moves)
  ros.callOnConnection({ op: 'advertise', topic: '/idle', type: 'std_msgs/msg/String', latch: true });
  ros.callOnConnection({ op: 'publish', topic: '/idle', msg: { data: 'at rest' } });
  ros.callOnConnection({ op: 'subscribe', topic: '/idle', type: 'std_msgs/msg/String' });
  while (link.dataAt === null) await new Promise((r) => setTimeout(r, 20));
  const last = link.dataAt;
  // a pong of a ping sent a second after the last message: everything sent before it has arrived
  const deadline = performance.now() + 30000;
  while (!(link.currentAt > last + 1000)) {
    assert.ok(performance.now() < deadline, 'no pong of a ping sent a second after the last message');
    await new Promise((r) => setTimeout(r, 20));
  }
  const now = performance.now();
  assert.equal(link.dataAt, last, 'no other message came');
  assert.ok(link.age(now) <= now - link.currentAt + 1e-6, `age ${link.age(now)} ms`);
  assert.ok(link.age(now) < now - last - 1000, 'the age does not count from the last message');
  const shown = Number(/data ([\d.]+) s old/.exec(link.describe(now))[1]);
  assert.ok(shown * 1000 <= now - link.currentAt + 50, `shown ${shown} s`);
  link.restart = () => {};
  link._drop();
  gw.proc.kill('SIGKILL');
});

test('a heavy moment of the page (heavy()) makes every link of the page patient', async () => {
  const a = new Link('ws://127.0.0.1:1/');
  const b = new Link('ws://127.0.0.1:1/');
  for (const link of [a, b]) for (let i = 0; i < 40; i++) link._measured(20);
  let done;
  const loading = new Promise((resolve) => { done = resolve; });
  assert.equal(heavy(loading), loading);
  assert.deepEqual([a.silence(), b.silence()], [5000, 5000]);   // a Python worker starting in the page
  done();
  await loading;
  await new Promise((resolve) => { setTimeout(resolve, 0); });
  assert.deepEqual([a.silence(), b.silence()], [SILENCE, SILENCE]);
});
