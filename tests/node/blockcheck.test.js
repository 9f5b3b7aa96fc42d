// The page's block check (ide/js/blocks/blockcheck.js) on the cases the gateway's is run on too
// (tests/lab/test_blockcheck.py): the page and the gateway refuse the same definitions.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { fileURLToPath, pathToFileURL } from 'node:url';
import path from 'node:path';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..');
const schemaText = readFileSync(path.join(root, 'ide', 'blockschema.json'), 'utf8');
const cases = JSON.parse(readFileSync(path.join(root, 'tests', 'node', 'blockcases.json'), 'utf8'));
const check = await import(pathToFileURL(path.join(root, 'ide', 'js', 'blocks', 'blockcheck.js')).href);

test('no block is taken before the schema is loaded', () => {
  assert.match(check.madeProblem(cases[0].made), /not loaded/);
});

test('the schema is loaded as the page loads it', async () => {
  const fetch = globalThis.fetch;
  globalThis.fetch = async () => ({ ok: true, json: async () => JSON.parse(schemaText) });
  try { await check.loadSchema(); } finally { globalThis.fetch = fetch; }
});

for (const c of cases) {
  test(`a made block: ${c.what}`, () => {
    const why = check.madeProblem(c.made);
    if (c.bad === false) assert.equal(why, null);
    else assert.ok(why && why.includes(c.bad), `${c.what}: ${why}`);
  });
}

for (const name of ['ros', 'turtlesim', 'rover']) {
  test(`the IDE's own set ${name} passes`, () => {
    const set = JSON.parse(readFileSync(path.join(root, 'ide', 'blocks', `${name}.json`), 'utf8'));
    assert.equal(check.setProblem(set, name), null);
  });
}
