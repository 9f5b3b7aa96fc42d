// "Make a block": turns a live topic, service or action into a block of its own.
// The definition (block JSON + rosgate spec) is saved with the program.
/* global Blockly */
import { normType } from '../robot/graph.js';
import { addCustomBlock, updateToolbox } from './toolbox.js';
import { t } from '../i18n.js';

const NUMERIC = /^(u?int(8|16|32|64)|float(32|64)|double|byte|char)$/;
const MAX_INPUTS = 8;

// Scalar leaf fields of a type: [{path, type}]. Arrays are left out (they keep their defaults),
// unless `arrays`: then numeric arrays come too, as {path, type, array: true}.
function leaves(typedefs, { arrays = false } = {}) {
  const byType = new Map(typedefs.map((d) => [normType(d.type), d]));
  const out = [];
  const walk = (def, prefix, depth) => def.fieldnames.forEach((name, i) => {
    const t = def.fieldtypes[i].replace(/<=\d+$/, '');
    const path = prefix ? `${prefix}.${name}` : name;
    if (def.fieldarraylen[i] !== -1) {
      if (arrays && NUMERIC.test(t)) out.push({ path, type: t, array: true });
      return;
    }
    const sub = byType.get(normType(t));
    if (sub && depth < 4) walk(sub, path, depth + 1);
    else if (NUMERIC.test(t) || t === 'bool' || t === 'string') out.push({ path, type: t });
  });
  if (typedefs[0]) walk(typedefs[0], '', 0);
  return out;
}

function shadowOf(type) {
  if (type === 'bool') return { type: 'logic_boolean', fields: { BOOL: 'FALSE' } };
  if (type === 'string') return { type: 'text', fields: { TEXT: '' } };
  return { type: 'math_number', fields: { NUM: 0 } };
}

function checkOf(type) {
  if (type === 'bool') return 'Boolean';
  if (type === 'string') return 'String';
  return 'Number';
}

// Nested template {a: {b: "$F0"}} from leaf paths.
function template(fields) {
  const tpl = {};
  fields.forEach((f, i) => {
    const parts = f.path.split('.');
    let o = tpl;
    for (const p of parts.slice(0, -1)) o = (o[p] ??= {});
    o[parts.at(-1)] = `$F${i}`;
  });
  return tpl;
}

// Builds the definition of a block; `kind` is publish | read | service | action.
export function buildDefinition({ kind, name, type, label, fields, responseFields = [] }) {
  const slug = `${kind}_${name}`.replace(/[^A-Za-z0-9]+/g, '_').replace(/^_+|_+$/g, '').toLowerCase();
  const typeName = `my_${slug}`;
  const used = fields.slice(0, MAX_INPUTS);
  let message = label.replace(/%/g, '%%');
  const args = [];
  const toolboxInputs = {};
  used.forEach((f, i) => {
    message += ` ${f.path} %${args.length + 1}`;
    args.push({ type: 'input_value', name: `F${i}`, check: checkOf(f.type) });
    toolboxInputs[`F${i}`] = { shadow: shadowOf(f.type) };
  });
  const json = { type: typeName, message0: message, args0: args, inputsInline: used.length <= 3, tooltip: `${kind} ${name} (${type})` };
  let spec;
  if (kind === 'publish') {
    Object.assign(json, { previousStatement: null, nextStatement: null });
    spec = { kind: 'publish', topic: name, type, msg: template(used) };
  } else if (kind === 'service') {
    if (responseFields.length) json.output = null; else Object.assign(json, { previousStatement: null, nextStatement: null });
    spec = { kind: 'call', service: name, type, args: template(used) };
    if (responseFields.length === 1) spec.field = responseFields[0].path;
  } else if (kind === 'action') {
    Object.assign(json, { previousStatement: null, nextStatement: null });
    spec = { kind: 'goal', action: name, type, args: template(used) };
  } else {
    const options = fields.flatMap((f) => (f.array ? REDUCERS.map(([text, how]) => [text(f.path), `${how}:${f.path}`]) : [[f.path, f.path]]));
    json.message0 = `${label.replace(/%/g, '%%')} %1`;
    json.args0 = [{ type: 'field_dropdown', name: 'FIELD', options: options.length ? options : [['(message)', '']] }];
    json.output = null;
    json.inputsInline = true;
    if (fields.some((f) => f.array)) {
      // a list field: read the message, then pick (min, max, mean, item i) from it
      json.mutator = PICK_MUTATOR;
      json.tooltip += '; a list gives its smallest, largest or mean number (NaN and inf left out), or item i (from 0)';
      spec = { kind: 'latest', topic: name, type, pick: '${FIELD}', index: 'I' };
    } else {
      spec = { kind: 'latest', topic: name, type, field: '${FIELD}' };
    }
    return { json, spec, toolboxInputs: {} };
  }
  return { json, spec, toolboxInputs };
}

// The reducers a reader offers for a list field: the option's text and the selector's prefix.
const REDUCERS = [
  [(p) => `smallest of ${p}`, 'min'],
  [(p) => `largest of ${p}`, 'max'],
  [(p) => `mean of ${p}`, 'mean'],
  [(p) => `${p} item i`, 'item'],
];

// A reader with list fields shows an input "i" while an 'item:' selector is chosen.
export const PICK_MUTATOR = 'rosgate_pick_mutator';
const PICK_MIXIN = {
  saveExtraState() { return { item: !!this.getInput('I') }; },
  loadExtraState(state) { this.showIndex_(!!state?.item, false); },
  showIndex_(on, withShadow = true) {
    const has = !!this.getInput('I');
    if (on && !has) {
      const input = this.appendValueInput('I').setCheck('Number').appendField('i');
      if (withShadow) input.connection.setShadowState({ type: 'math_number', fields: { NUM: 0 } });
    } else if (!on && has) {
      this.removeInput('I');
    }
  },
};

// Registers the reader's mutator (js/ide/main.js calls this once, before any block is defined).
export function registerMakeBlock() {
  if (Blockly.Extensions.isRegistered(PICK_MUTATOR)) return;
  Blockly.Extensions.registerMutator(PICK_MUTATOR, PICK_MIXIN, function () {
    const block = this;
    this.getField('FIELD').setValidator(function (v) {
      block.showIndex_(String(v).startsWith('item:'));
      return undefined;
    });
  });
}

export class MakeBlockDialog {
  constructor(dialog, graph, add) {
    this.dlg = dialog;
    this.graph = graph;
    this.add = add;
    this.kind = dialog.querySelector('[name=kind]');
    this.name = dialog.querySelector('[name=rosname]');
    this.names = dialog.querySelector('#make-names');
    this.label = dialog.querySelector('[name=label]');
    this.msg = dialog.querySelector('.make-msg');
    this.kind.onchange = () => this.fillNames();
    this.name.onchange = () => { this.label.value = this.defaultLabel(); };
    dialog.querySelector('[data-act=cancel]').onclick = () => dialog.close();
    dialog.querySelector('[data-act=create]').onclick = () => this.create();
  }

  graphKind() { return { publish: 'topic', read: 'topic', service: 'service', action: 'action' }[this.kind.value]; }

  defaultLabel() {
    const verb = { publish: 'publish to', read: 'latest of', service: 'call', action: 'run action' }[this.kind.value];
    return `${verb} ${this.name.value}`;
  }

  fillNames() {
    this.names.replaceChildren(...this.graph.names(this.graphKind()).map((n) => new Option(n, n)));
  }

  async open() {
    this.msg.textContent = '';
    if (this.graph.connected) await this.graph.refresh().catch(() => {});
    this.fillNames();
    this.dlg.showModal();
  }

  // Creates the block for kind/name (also callable from tests); resolves to its definition.
  async make(kind, name, label) {
    const gk = { publish: 'topic', read: 'topic', service: 'service', action: 'action' }[kind];
    let type = this.graph.typeOf(gk, name);
    if (!type) {
      await this.graph.refresh();
      type = this.graph.typeOf(gk, name);
    }
    if (!type) throw new Error(`no ${gk} named ${name} on the gateway`);
    const detailKind = { publish: 'msg', read: 'msg', service: 'request', action: 'goal' }[kind];
    const fields = leaves(await this.graph.details(detailKind, type), { arrays: kind === 'read' });
    const responseFields = kind === 'service' ? leaves(await this.graph.details('response', type)) : [];
    const def = buildDefinition({ kind, name, type, label: label || `${kind} ${name}`, fields, responseFields });
    this.add(def);
    return def;
  }

  async create() {
    const name = this.name.value.trim();
    if (!name) { this.msg.textContent = t('make.choose'); return; }
    try {
      const def = await this.make(this.kind.value, name, this.label.value.trim() || this.defaultLabel());
      this.msg.textContent = t('make.made', { type: def.json.type });
      this.dlg.close();
    } catch (e) {
      this.msg.textContent = e.message;
    }
  }
}

// "Make a block" and "Publish my blocks" in the toolbox's "My blocks", and the shared blocks a
// program uses saved with it.
export function mountMakeBlock(ide) {
  const { workspace, console: consoleView } = ide;
  const maker = new MakeBlockDialog(document.querySelector('#dlg-make'), ide.graph, (def) => addCustomBlock(ide, def));
  workspace.registerButtonCallback('makeBlock', () => maker.open());
  ide.publishBlocks = () => ide.blockSets.publish(ide.custom).then(
    (n) => { consoleView.info(t('ide.blocks.published', { n })); updateToolbox(ide); return n; },
    (e) => { consoleView.error(t('ide.blocks.publish.failed', { error: e.message })); throw e; });
  workspace.registerButtonCallback('publishBlocks', () => ide.publishBlocks().catch(() => {}));
  workspace.addChangeListener((e) => {   // a shared block in the program: saved with it
    if (e.type !== Blockly.Events.BLOCK_CREATE) return;
    for (const id of e.ids ?? []) {
      const made = ide.blockSets.sharedOf(workspace.getBlockById(id)?.type);
      if (made && !ide.custom.some((c) => c.json.type === made.json.type)) ide.custom.push(made);
    }
  });
  ide.makeBlock = maker;
}
