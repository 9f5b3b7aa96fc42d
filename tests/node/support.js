// What the roslib tests share: deadlines on roslib's callbacks, and a sim gateway of their own.
import { spawn } from 'node:child_process';
import { once } from 'node:events';
import { fileURLToPath } from 'node:url';
import path from 'node:path';

export const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..');
const python = process.env.ROSGATE_PYTHON || path.join(root, '.venv', 'bin', 'python');

export function withTimeout(promise, ms, what) {
  let timer;
  const timeout = new Promise((_, reject) => {
    timer = setTimeout(() => reject(new Error(`${what}: no answer within ${ms} ms`)), ms);
  });
  return Promise.race([promise, timeout]).finally(() => clearTimeout(timer));
}

// roslib's callback API as promises
export const call = (fn, ms = 5000, what = 'call') =>
  withTimeout(new Promise((resolve, reject) => fn(resolve, reject)), ms, what);

// A sim gateway (demo nodes, fast Fibonacci, no robot unless `extra` flags name one): { proc, url, stop() }.
export async function startGateway(extra = []) {
  const proc = spawn(python, ['-m', 'gateway', '--port', '0', '--address', '127.0.0.1', '--robot', 'none',
    '--fibonacci-interval', '0.05', '--programs-dir', path.join(root, '.venv', 'node-test-programs'), ...extra],
  { cwd: root, stdio: ['ignore', 'pipe', 'inherit'] });
  let line = '';
  for await (const chunk of proc.stdout) {
    line += chunk;
    if (line.includes('\n')) break;
  }
  proc.stdout.resume();
  const stop = async () => {
    if (proc.exitCode === null) {
      proc.kill('SIGTERM');
      await once(proc, 'exit');
    }
  };
  return { proc, url: line.match(/websocket (ws:\/\/\S+)/)[1], stop };
}
