import { messageState } from './msgblock.js';
import { shared } from '../robot/graph.js';
import { withNamespace } from '../../runtime/util.js';
import { t } from '../i18n.js';

// A dropdown of live ROS names (topics, services, actions, types, fields) that also
// takes free text, and the block extensions that fill a block's TYPE from its name.
/* global Blockly */

export const OTHER = '\u0000other';
const g = () => shared.graph;
const typed = new Map();     // names typed by hand, per kind, offered again in the menus


export class FieldRosName extends Blockly.FieldDropdown {
  constructor(kind, value, validator) {
    // Blockly calls the generator as a method of the field, before `kind` is set
    super(function () { return FieldRosName.prototype.menu.call(this); }, validator);
    this.kind = kind;
    this.setValue(value ?? '');
  }

  static fromJson(options) {
    return new FieldRosName(options.kind, options.value ?? '');
  }

  names() {
    if (!g()) return [];
    const block = this.getSourceBlock();
    switch (this.kind) {
      case 'topic': case 'service': case 'action': return g().names(this.kind, shared.scope?.ns() ?? '');
      case 'msgtype': return g().messageTypes();
      case 'srvtype': return g().serviceTypes();
      case 'actiontype': return g().actionTypes();
      case 'field': {
        const type = block?.getFieldValue('TYPE');
        return type ? g().fieldPaths(type) : [];
      }
      default: return [];
    }
  }

  menu() {
    const seen = new Set();
    const opts = [];
    const add = (v) => { if (v && !seen.has(v)) { seen.add(v); opts.push([v, v]); } };
    add(this.value_);
    for (const n of this.names()) add(n);
    for (const n of typed.get(this.kind) ?? []) add(n);
    opts.push([t(this.kind === 'field' ? 'field.type.field' : 'field.type.name'), OTHER]);
    if (g()?.connected && !g()._refreshing && this.kind !== 'field') g().refresh().catch(() => {});
    return opts;
  }

  doClassValidation_(v) {
    if (v === OTHER) return v;
    return typeof v === 'string' ? v : null;
  }

  doValueUpdate_(v) {
    this.value_ = v;
    this.isDirty_ = true;
    this.selectedOption = [v || ' ', v];
  }

  onItemSelected_(menu, item) {
    if (item.getValue() !== OTHER) { this.setValue(item.getValue()); return; }
    const label = t(['topic', 'service', 'action', 'field'].includes(this.kind) ? `field.ask.${this.kind}` : 'field.ask.name');
    Blockly.dialog.prompt(`${label}:`, this.value_ ?? '', (text) => {
      if (text === null || text === undefined) return;
      text = text.trim();
      if (!text) return;
      if (!typed.has(this.kind)) typed.set(this.kind, new Set());
      typed.get(this.kind).add(text);
      this.setValue(text);
    });
  }

  getText_() {
    if (!this.value_) return '…';
    return this.shortText ? this.value_.split('/').pop() : this.value_;
  }
}

Blockly.fieldRegistry.register('field_rosname', FieldRosName);

// NAME kinds each block family uses.
const NAME_FIELDS = { TOPIC: 'topic', SERVICE: 'service', ACTION: 'action' };
const DETAIL_KIND = { topic: 'msg', service: 'request', action: 'goal' };
const MSG_INPUT = { topic: 'MSG', service: 'REQUEST', action: 'GOAL' };

// Keeps TYPE in step with the chosen name and offers a matching message block.
Blockly.Extensions.register('ros_typed_name', function () {
  const block = this;
  const nameField = Object.keys(NAME_FIELDS).find((f) => block.getField(f));
  if (!nameField) return;
  const kind = NAME_FIELDS[nameField];
  block.getField(nameField).setValidator(function (name) {
    if (name === OTHER) return undefined;
    if (block.isInFlyout || block.workspace.isFlyout) return undefined;
    // a block being loaded (a program, undo, a drag out of the toolbox) keeps its saved message
    if (!Blockly.Events.isEnabled()) return undefined;
    if (!g() || name === this.getValue()) return undefined;
    setTimeout(() => fillType(block, kind, name), 0);
    return undefined;
  });
  // a block dragged out of the toolbox gets a message block of its type
  const inputName = MSG_INPUT[kind];
  if (block.getInput(inputName) && !block.workspace.isFlyout) {
    setTimeout(() => {
      const type = block.getFieldValue('TYPE');
      if (block.disposed || !type || !g()?.connected || block.getInputTargetBlock(inputName)) return;
      attachMessage(block, inputName, DETAIL_KIND[kind], type);
    }, 0);
  }
});

// The name a generic block's field stands for on this page (its station's, or as it is).
export function resolvedName(kind, name) {
  const scope = shared.scope;
  return scope?.inNamespace(kind, name) ? withNamespace(scope.ns(), name) : name;
}

async function fillType(block, kind, picked) {
  if (block.isDeadOrDying?.() || block.disposed) return;
  const name = resolvedName(kind, picked);
  let type = g().typeOf(kind, name);
  if (!type && g().connected) {
    try {
      if (kind === 'topic') type = (await g().call('/rosapi/topic_type', { topic: name })).type;
      if (kind === 'service') type = (await g().call('/rosapi/service_type', { service: name })).type;
      if (kind === 'action') type = (await g().call('/rosapi/action_type', { action: name })).type;
    } catch { type = ''; }
  }
  if (!type || block.disposed) return;
  Blockly.Events.setGroup(true);
  try {
    block.setFieldValue(type, 'TYPE');
    const inputName = MSG_INPUT[kind];
    if (inputName && block.getInput(inputName)) {
      await attachMessage(block, inputName, DETAIL_KIND[kind], type);
    }
  } finally {
    Blockly.Events.setGroup(false);
  }
}

// Puts a message block of `type` into the block's input unless one of that type is there.
// The message block it replaces is deleted, never left loose; of two calls for one block (the
// name picked twice quickly) the last one wins.
export async function attachMessage(block, inputName, detailKind, type) {
  const input = block.getInput(inputName);
  const wanted = (current) => !current || (current.type === 'ros_message' && current.msgType !== type);
  if (!wanted(input.connection.targetBlock())) return;   // that type already, or a user's own expression
  const ticket = (block.attachTicket_ = (block.attachTicket_ ?? 0) + 1);
  let defs;
  try { defs = await g().details(detailKind, type); } catch { return; }
  if (block.disposed || ticket !== block.attachTicket_) return;
  const current = input.connection.targetBlock();
  if (!wanted(current)) return;
  const group = Blockly.Events.getGroup();
  if (!group) Blockly.Events.setGroup(true);
  try {
    if (current) current.dispose(false);
    const child = Blockly.serialization.blocks.append(messageState(detailKind, type, defs), block.workspace);
    input.connection.connect(child.outputConnection);
  } finally {
    if (!group) Blockly.Events.setGroup(false);
  }
}
