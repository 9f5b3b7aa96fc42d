// Programs as JSON: autosave in the browser, files, the gateway's library, share links.
// What comes from a link, a file or the library is checked before it is opened: its own blocks
// against the block schema (js/blocks/blockcheck.js), as data.
/* global Blockly */
import { madeProblem } from '../blocks/blockcheck.js';
import { api, ApiError } from '../link/api.js';

export const FORMAT = 'rosgate-program';
const AUTOSAVE_KEY = 'rosgate.autosave';

// {format, version, name, robot, blocks: [custom block definitions], workspace}
export function makeProgram(workspace, { name, robot, blocks }) {
  return {
    format: FORMAT,
    version: 1,
    name: name || 'program',
    robot: robot || 'any',
    blocks: blocks || [],
    workspace: Blockly.serialization.workspaces.save(workspace),
  };
}

// A text program: {format, version, kind: 'text', lang: 'python' | 'javascript', name, robot, text}
export const TEXT_LANGS = ['python', 'javascript'];
export function makeTextProgram({ name, robot, lang, text }) {
  return { format: FORMAT, version: 1, kind: 'text', lang, name: name || 'program', robot: robot || 'any', text };
}

export const isText = (p) => p?.kind === 'text';

export function checkProgram(p) {
  if (!p || typeof p !== 'object' || p.format !== FORMAT) throw new Error('not a rosgate program');
  if (p.blocks !== undefined && !Array.isArray(p.blocks)) throw new Error('not a rosgate program: "blocks" is a list');
  for (const [i, made] of (p.blocks ?? []).entries()) {
    const why = madeProblem(made, `blocks[${i}]`);
    if (why) throw new Error(why);
  }
  if (isText(p)) {
    if (typeof p.text !== 'string' || !TEXT_LANGS.includes(p.lang)) throw new Error('not a rosgate text program');
  } else if (!p.workspace) {
    throw new Error('not a rosgate program');
  }
  return p;
}

export function autosave(program) {
  try { localStorage.setItem(AUTOSAVE_KEY, JSON.stringify(program)); } catch { /* quota */ }
}

// The last block program, kept while a text program is open ("Edit as text" leaves it as it was).
const BLOCKS_KEY = 'rosgate.autosave.blocks';
export function keepBlocks(program) {
  try { localStorage.setItem(BLOCKS_KEY, JSON.stringify(program)); } catch { /* quota */ }
}
export function keptBlocks() {
  try { const text = localStorage.getItem(BLOCKS_KEY); return text ? checkProgram(JSON.parse(text)) : null; } catch { return null; }
}

export function loadAutosave() {
  try {
    const text = localStorage.getItem(AUTOSAVE_KEY);
    return text ? checkProgram(JSON.parse(text)) : null;
  } catch { return null; }
}

export function pickFile(accept = '.json,application/json') {
  return new Promise((resolve) => {
    const input = document.createElement('input');
    input.type = 'file';
    input.accept = accept;
    input.onchange = async () => resolve(input.files[0] ? await input.files[0].text() : null);
    input.click();
  });
}

export function safeName(name) {
  return String(name || 'program').replace(/[^A-Za-z0-9 _-]+/g, '_').replace(/^[ ]+/, '').slice(0, 64) || 'program';
}

// ---- share links: the program deflated into the URL fragment --------------
function toBase64Url(bytes) {
  let s = '';
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(s).replace(/\+/g, '-').replace(/\//g, '_').replace(/=+$/, '');
}

function fromBase64Url(text) {
  const s = atob(text.replace(/-/g, '+').replace(/_/g, '/'));
  return Uint8Array.from(s, (c) => c.charCodeAt(0));
}

async function pipe(bytes, stream) {
  const out = new Response(new Blob([bytes]).stream().pipeThrough(stream));
  return new Uint8Array(await out.arrayBuffer());
}

// shared: the sharer's signature of the program's JSON text ({by, sig}: js/run/foreign.js), carried with it
export async function shareLink(program, shared = null) {
  const bytes = new TextEncoder().encode(JSON.stringify(shared?.sig ? { ...program, shared } : program));
  const packed = await pipe(bytes, new CompressionStream('deflate-raw'));
  const url = new URL(location.href);
  url.search = '';
  url.hash = `program=${toBase64Url(packed)}`;
  return url.toString();
}

// {program, shared, text}: the link's program, the signature it carries and the program's JSON text
// as it was signed (the signature is not part of the program)
export async function programFromHash(hash = location.hash) {
  const m = /[#&]program=([A-Za-z0-9_-]+)/.exec(hash);
  if (!m) return null;
  const bytes = await pipe(fromBase64Url(m[1]), new DecompressionStream('deflate-raw'));
  const { shared = null, ...program } = JSON.parse(new TextDecoder().decode(bytes));
  return { program: checkProgram(program), shared, text: JSON.stringify(program) };
}

// ---- the gateway's program library ------------------------------------------
// an error says "<status> <the gateway's words>" (the library dialog shows it)
async function programs(path, options = {}) {
  try { return await api(`api/programs${path}`, options); } catch (e) {
    throw e instanceof ApiError ? new Error(`${e.status} ${e.body?.error || e.statusText}`) : e;
  }
}

// `owner`: the space a program is in (with --auth each signed-in name has one; null: shared).
const inSpace = (name, owner) => `/${encodeURIComponent(name)}${owner ? `?owner=${encodeURIComponent(owner)}` : ''}`;

export const library = {
  list: async () => (await programs('')).programs,
  load: async (name, owner = null) => checkProgram(await programs(inSpace(name, owner))),
  // `python`: the program's generated Python, stored with it so the gateway can run the program
  // by name (POST /api/runs {"program": name}); opening it again uses only the workspace.
  save: (name, program, python = null) => programs(`/${encodeURIComponent(name)}`, {
    method: 'PUT', body: python == null ? program : { ...program, python },
  }),
  remove: (name, owner = null) => programs(inSpace(name, owner), { method: 'DELETE' }),
};
