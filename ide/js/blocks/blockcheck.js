// Block definitions from outside the IDE are data, never code: checked against the IDE's block
// schema (blockschema.json, which the gateway checks too: gateway/web/blockcheck.py) before Blockly
// sees them. A share link's block with helpUrl "javascript:..." ran in the gateway's origin when
// someone picked Help; with the teacher signed in it published itself to the class's library.
// What comes from a link, a file, the class's library, a --blocks-dir set or a student's report is
// checked here: keys and kinds of values as the schema lists them, no HTML, no javascript:, data:
// or other such address anywhere, a url empty, http(s) or a path of this site. Help itself opens
// only an http(s) page (guardHelp), whatever defined the block.
/* global Blockly */

let schema = null;

const TAG = /<[A-Za-z!/?]/;
const SCHEME = /^([a-z][a-z0-9+.-]*):/;
const HIDDEN = /[\x00-\x20\x7f]+/g;   // what a browser drops from an address before reading its scheme
const URL_ = /^https?:\/\/[^\s<>"'`\\]+$/i;
const SITE_PATH = /^(?!\/\/)[A-Za-z0-9_./%-]+$/;
const TYPE = /^[A-Za-z][A-Za-z0-9_]{0,99}$/;
const WORD = /^[A-Za-z0-9_. -]{0,100}$/;
const COLOUR = /^(#[0-9a-fA-F]{6}|\d{1,3}|%\{BKY_[A-Z0-9_]+\})$/;
const NUMBERED = /^([A-Za-z]+)(\d)$/;
const ALIGN = ['LEFT', 'RIGHT', 'CENTRE', 'CENTER'];

/** Loads the schema (once, at the page's start); until then every block from outside is refused. */
export async function loadSchema(url = 'blockschema.json') {
  const res = await fetch(url, { cache: 'no-cache' });
  if (!res.ok) throw new Error(`${url}: ${res.status}`);
  schema = await res.json();
  return schema;
}

const text = (v) => typeof v === 'string';
const number = (v) => typeof v === 'number' && Number.isFinite(v);

const KINDS = {
  type: (v) => text(v),
  text: (v) => text(v),
  word: (v) => text(v) && WORD.test(v),
  words: (v) => Array.isArray(v) && v.every((x) => text(x) && WORD.test(x)),
  bool: (v) => typeof v === 'boolean',
  number,
  scalar: (v) => v === null || ['string', 'number', 'boolean'].includes(typeof v),
  align: (v) => ALIGN.includes(v),
  check: (v) => v === null || text(v) || (Array.isArray(v) && v.every(text)),
  colour: (v) => number(v) || (text(v) && COLOUR.test(v)),
  url: (v) => text(v) && (v === '' || URL_.test(v) || SITE_PATH.test(v)),
  extensions: (v, made) => Array.isArray(v) && !made && v.every((x) => schema.extensions.includes(x)),
  mutator: (v, made) => (made ? schema.madeMutators : schema.mutators).includes(v),
  spec: (v) => v !== null && typeof v === 'object' && !Array.isArray(v) && schema.specKinds.includes(v.kind),
  data: () => true,
};

function textProblem(s, where) {
  if (s.length > schema.maxString) return `${where}: longer than ${schema.maxString} characters`;
  if (TAG.test(s)) return `${where}: no HTML in a block (${JSON.stringify(s.slice(0, 60))})`;
  const scheme = SCHEME.exec(s.replace(HIDDEN, '').toLowerCase());
  if (scheme && schema.badSchemes.includes(scheme[1])) return `${where}: no ${scheme[1]}: address in a block`;
  return null;
}

/** Every string in a JSON value as the schema allows; not deeper than maxDepth. */
export function dataProblem(value, where, depth = 0) {
  if (!schema) return `${where}: the block schema is not loaded`;
  if (depth > schema.maxDepth) return `${where}: nested deeper than ${schema.maxDepth} levels`;
  if (text(value)) return textProblem(value, where);
  if (typeof value === 'number' && !Number.isFinite(value)) return `${where}: not a finite number`;
  if (value === null || typeof value !== 'object') return null;
  for (const [key, item] of Object.entries(value)) {
    const why = textProblem(key, `${where} (a key)`) ?? dataProblem(item, Array.isArray(value) ? `${where}[${key}]` : `${where}.${key}`, depth + 1);
    if (why) return why;
  }
  return null;
}

function valueProblem(kind, value, where, made) {
  if (kind === 'args') return argsProblem(value, where);
  if (kind === 'options') return optionsProblem(value, where);
  const test = KINDS[kind];
  if (test && !test(value, made)) return `${where}: not a ${kind} (${JSON.stringify(value)?.slice(0, 80)})`;
  return null;
}

function argsProblem(args, where) {
  if (!Array.isArray(args) || args.length > schema.maxArgs) return `${where}: a list of at most ${schema.maxArgs} inputs and fields`;
  for (const [i, arg] of args.entries()) {
    const at = `${where}[${i}]`;
    if (!arg || typeof arg !== 'object' || !schema.argTypes.includes(arg.type)) return `${at}.type: one of ${schema.argTypes.join(', ')}`;
    for (const [key, value] of Object.entries(arg)) {
      const kind = schema.arg[key];
      if (!kind) return `${at}.${key}: not a key of a block's input or field`;
      if (kind !== 'argType') { const why = valueProblem(kind, value, `${at}.${key}`, false); if (why) return why; }
    }
  }
  return null;
}

function optionsProblem(options, where) {
  if (!Array.isArray(options)) return `${where}: a list of [label, value]`;
  for (const [i, option] of options.entries()) {
    const label = Array.isArray(option) && option.length === 2 && text(option[1]) ? option[0] : undefined;
    if (label && typeof label === 'object') {
      if (Object.keys(label).some((k) => !['src', 'width', 'height', 'alt'].includes(k))) return `${where}[${i}]: an image option is {src, width, height, alt}`;
      const why = valueProblem('url', label.src ?? '', `${where}[${i}].src`, false);
      if (why) return why;
    } else if (!text(label)) return `${where}[${i}]: [label, value], both text (or an image label)`;
  }
  return null;
}

/** Why a block definition (Blockly JSON with its rosgate spec) is not data the IDE takes, or null.
 *  made: a block of "make a block" (a program's own, the class's library). */
export function blockProblem(block, where = 'block', { made = false } = {}) {
  if (!schema) return `${where}: the block schema is not loaded`;
  if (!block || typeof block !== 'object' || Array.isArray(block)) return `${where}: a block definition is a JSON object`;
  const why = dataProblem(block, where);
  if (why) return why;
  for (const [key, value] of Object.entries(block)) {
    const m = NUMBERED.exec(key);
    const kind = schema.block[m && schema.numbered.includes(m[1]) ? m[1] : key];
    if (!kind) return `${where}.${key}: not a key of a block`;
    const bad = valueProblem(kind, value, `${where}.${key}`, made);
    if (bad) return bad;
  }
  if (!text(block.type) || !TYPE.test(block.type)) return `${where}.type: letters, digits and _, starting with a letter`;
  if (made && !block.type.startsWith(schema.madePrefix)) return `${where}.type: a made block's type starts with ${schema.madePrefix}`;
  return null;
}

/** A made block: {json, spec, toolboxInputs}. */
export function madeProblem(made, where = 'block') {
  if (!schema) return `${where}: the block schema is not loaded`;
  if (!made || typeof made !== 'object' || !made.json || typeof made.json !== 'object') {
    return `${where}: a made block is {"json": {...}, "spec": {...}, "toolboxInputs": {...}}`;
  }
  for (const [key, value] of Object.entries(made)) {
    const kind = schema.made[key];
    if (!kind) return `${where}.${key}: not a key of a made block (json, spec, toolboxInputs)`;
    const why = kind === 'block' ? blockProblem(value, `${where}.json`, { made: true })
      : dataProblem(value, `${where}.${key}`) ?? valueProblem(kind, value, `${where}.${key}`, true);
    if (why) return why;
  }
  return null;
}

/** A --blocks-dir set as the gateway serves it: its blocks, its toolbox and shadows as data. */
export function setProblem(set, where = 'set') {
  for (const key of ['toolbox', 'shadows', 'name', 'robot', 'colour']) {
    if (key in (set ?? {})) { const why = dataProblem(set[key], `${where}.${key}`); if (why) return why; }
  }
  for (const [i, block] of (set?.blocks ?? []).entries()) {
    const why = blockProblem(block, `${where}.blocks[${i}]`);
    if (why) return why;
  }
  return null;
}

/** Help opens an http(s) page only, whatever defined the block (a set, a link, a report). */
export function guardHelp() {
  const proto = Blockly.BlockSvg?.prototype;
  if (!proto || proto.showHelp?.guarded) return;
  const show = proto.showHelp;
  proto.showHelp = function showHelp() {
    const url = typeof this.helpUrl === 'function' ? this.helpUrl() : this.helpUrl;
    if (!text(url) || !URL_.test(url.trim())) return;
    show.call(this);
  };
  proto.showHelp.guarded = true;
}
