// The pages' one JSON API helper (ide/js/link/api.js) against a real gateway's program library: an answer as
// JSON, a 204 as null, the gateway's own words in an ApiError with its status, a missing route as an ApiError
// a caller can read as "nothing", the query and the JSON body as the handlers read them.
import { after, before, test } from 'node:test';
import assert from 'node:assert/strict';
import { api, ApiError } from '../../ide/js/link/api.js';
import { startGateway } from './support.js';

let gw;
let http;
const NAME = `api helper ${process.pid}`;

before(async () => {
  gw = await startGateway();
  http = gw.url.replace(/^ws/, 'http');
});
after(async () => { await api(`${http}api/programs/${encodeURIComponent(NAME)}`, { method: 'DELETE' }).catch(() => {}); await gw?.stop(); });

test('a body goes out as JSON and the answer comes back as JSON; a DELETE answered 204 is null', async () => {
  const program = { name: NAME, blocks: { blocks: [] } };
  const saved = await api(`${http}api/programs/${encodeURIComponent(NAME)}`, { method: 'PUT', body: program });
  assert.equal(saved.name, NAME);
  assert.deepEqual(await api(`${http}api/programs/${encodeURIComponent(NAME)}`), program);
  const { programs } = await api(`${http}api/programs`);
  assert.ok(programs.some((p) => p.name === NAME), programs);
  assert.equal(await api(`${http}api/programs/${encodeURIComponent(NAME)}`, { method: 'DELETE' }), null);
});

test("an error answer throws ApiError with the gateway's words, its status and its body", async () => {
  const bad = await api(`${http}api/programs/${encodeURIComponent(' no')}`).catch((e) => e);
  assert.ok(bad instanceof ApiError && bad instanceof Error, bad);
  assert.equal(bad.status, 400);
  assert.equal(bad.message, bad.body.error);
  assert.match(bad.message, /name/i);
  const gone = await api(`${http}api/programs/nothing-here-${process.pid}`).catch((e) => e);
  assert.equal(gone.status, 404);
  assert.ok(gone.message && gone.message !== 'HTTP 404', gone.message);   // the gateway's words, not the status alone
});

test('a route the gateway does not have is an ApiError with the status, which a caller may read as nothing', async () => {
  const e = await api(`${http}api/no-such-route`).catch((err) => err);
  assert.ok(e instanceof ApiError, e);
  assert.equal(e.status, 404);
  const nothing = await api(`${http}api/no-such-route`).catch((err) => (err instanceof ApiError ? null : Promise.reject(err)));
  assert.equal(nothing, null);
});

test('a network failure is not an ApiError: fetch threw it', async () => {
  const e = await api('http://127.0.0.1:1/api/programs').catch((err) => err);
  assert.ok(e instanceof Error && !(e instanceof ApiError), e);
});

test('the query is made the URL\'s query, after one the path already has', async () => {
  const seen = [];
  const real = globalThis.fetch;
  globalThis.fetch = (url, init) => { seen.push(url); return real(url, init); };
  try {
    await api(`${http}api/programs`, { query: { owner: 'x y' } }).catch(() => {});
    await api(`${http}api/programs?all=1`, { query: { owner: 'z' } }).catch(() => {});
  } finally { globalThis.fetch = real; }
  assert.deepEqual(seen, [`${http}api/programs?owner=x+y`, `${http}api/programs?all=1&owner=z`]);
});
