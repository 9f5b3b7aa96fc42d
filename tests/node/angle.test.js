// angleDiff (ide/runtime/util.js) answers at once for any number: a loop of 2*pi steps never
// ended for 1e20. Each call runs in a child node with a timeout, so a hang fails instead of blocking.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { spawnSync } from 'node:child_process';
import { fileURLToPath, pathToFileURL } from 'node:url';
import path from 'node:path';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..');
const util = pathToFileURL(path.join(root, 'ide', 'runtime', 'util.js')).href;
const HANG_MS = 30000;   // the closed form answers in microseconds, a loop over 1e20 never does
const TAU = 2 * Math.PI;

const child = `
const [file, a, b] = process.argv.slice(1);
const { angleDiff } = await import(file);
const d = angleDiff(Number(a), Number(b));
console.log(JSON.stringify(Number.isNaN(d) ? 'NaN' : d));
`;

function angleDiffInChild(a, b) {
  const r = spawnSync(process.execPath, ['--input-type=module', '-e', child, util, String(a), String(b)],
    { encoding: 'utf8', timeout: HANG_MS });
  assert.equal(r.error?.code, undefined, `angleDiff(${a}, ${b}) gave no answer within ${HANG_MS} ms`);
  assert.equal(r.status, 0, r.stderr);
  const d = JSON.parse(r.stdout);
  return d === 'NaN' ? NaN : d;
}

const near = (got, want) => assert.ok(Math.abs(got - want) < 1e-9, `${got} is not ${want}`);

for (const [a, b] of [[1e20, 0], [-1e20, 0], [7, 0], [-Math.PI, 0], [3 * Math.PI, 0], [0.1, TAU - 0.1]]) {
  test(`angleDiff(${a}, ${b}) is wrapped into (-pi, pi] at once`, () => {
    const d = angleDiffInChild(a, b);
    assert.ok(d > -Math.PI && d <= Math.PI, `${d} out of range`);
    const turns = (a - b - d) / TAU;        // a whole number of turns apart
    if (Math.abs(a - b) < 1e6) near(turns, Math.round(turns));
  });
}

test('angleDiff of 7 and of -pi', () => {
  near(angleDiffInChild(7, 0), 7 - TAU);
  near(angleDiffInChild(-Math.PI, 0), Math.PI);
});

for (const [a, b] of [[Infinity, 0], [-Infinity, 0], [NaN, 0], [0, Infinity]]) {
  test(`angleDiff(${a}, ${b}) is NaN at once`, () => {
    assert.ok(Number.isNaN(angleDiffInChild(a, b)));
  });
}
