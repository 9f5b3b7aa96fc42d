// The message-literal block: one input per field of a ROS type (from rosapi typedefs).
// The field list is saved with the block, so a program loads and generates offline.
/* global Blockly */
import { normType, shared } from '../robot/graph.js';
import { t } from '../i18n.js';

const NUMERIC = /^(u?int(8|16|32|64)|float(32|64)|double|float|byte|char|octet)$/;
const LABEL = { msg: t('msg.message'), request: t('msg.request'), goal: t('msg.goal') };
const TYPE_KIND = { msg: 'msgtype', request: 'srvtype', goal: 'actiontype' };

function fieldsOf(def) {
  return def.fieldnames.map((name, i) => ({
    name, type: def.fieldtypes[i], array: def.fieldarraylen[i],
  }));
}

function shadowFor(f, byType) {
  if (f.array !== -1) return null;
  const base = f.type.replace(/<=\d+$/, '');
  if (NUMERIC.test(base)) return { type: 'math_number', fields: { NUM: 0 } };
  if (base === 'bool' || base === 'boolean') return { type: 'logic_boolean', fields: { BOOL: 'FALSE' } };
  if (base === 'string' || base === 'wstring') return { type: 'text', fields: { TEXT: '' } };
  const def = byType.get(normType(base));
  return def ? nestedState('msg', base, def, byType) : null;
}

function nestedState(kind, type, def, byType) {
  const fields = fieldsOf(def);
  const inputs = {};
  for (const f of fields) {
    const s = shadowFor(f, byType);
    if (s) inputs[`F_${f.name}`] = { shadow: s };
  }
  const state = {
    type: 'ros_message',
    extraState: { kind, type, fields },
    fields: { TYPE: type },
    inputs,
  };
  return state;
}

// Serialisation state of a ros_message block for `type`, with default shadows in every field.
export function messageState(kind, type, typedefs) {
  const byType = new Map(typedefs.map((d) => [normType(d.type), d]));
  return nestedState(kind, type, typedefs[0], byType);
}

export const MESSAGE_MIXIN = {
  msgKind: 'msg',
  msgType: '',
  msgFields: [],

  saveExtraState() {
    return { kind: this.msgKind, type: this.msgType, fields: this.msgFields };
  },

  loadExtraState(state) {
    this.msgKind = state.kind || 'msg';
    this.msgType = state.type || '';
    this.msgFields = state.fields || [];
    this.updateShape_();
  },

  // Rebuilds the inputs for a type and fills them with default values.
  setMessage(kind, type, typedefs) {
    const state = messageState(kind, type, typedefs);
    this.msgKind = kind;
    this.msgType = type;
    this.msgFields = state.extraState.fields;
    this.updateShape_();
    this.setFieldValue(type, 'TYPE');
    for (const [name, input] of Object.entries(state.inputs)) {
      this.getInput(name)?.connection.setShadowState(input.shadow);
    }
  },

  updateShape_() {
    // a message of a few plain fields (Vector3, Point, Color) sits on one row: x ( ) y ( ) z ( )
    const plain = (f) => f.array === -1 && /^(u?int(8|16|32|64)|float(32|64)?|double|byte|char|octet|bool(ean)?|w?string)(<=\d+)?$/.test(f.type);
    this.setInputsInline(this.msgFields.length > 0 && this.msgFields.length <= 4 && this.msgFields.every(plain));
    const keep = new Set(this.msgFields.map((f) => `F_${f.name}`));
    for (const input of [...this.inputList]) {
      if (input.name.startsWith('F_') && !keep.has(input.name)) this.removeInput(input.name);
    }
    this.getField('KIND')?.setValue(LABEL[this.msgKind] ?? LABEL.msg);
    const typeField = this.getField('TYPE');
    if (typeField) typeField.kind = TYPE_KIND[this.msgKind] ?? 'msgtype';
    for (const f of this.msgFields) {
      const name = `F_${f.name}`;
      if (this.getInput(name)) continue;
      const label = f.array === -1 ? f.name : `${f.name} [ ]`;
      this.appendValueInput(name).setAlign(Blockly.inputs.Align.RIGHT).appendField(label);
    }
  },

  onTypeChosen_(type) {
    const graph = shared.graph;
    if (!graph || !type || type === this.msgType || this.isInFlyout) return;
    graph.details(this.msgKind, type).then((defs) => {
      if (this.disposed) return;
      Blockly.Events.setGroup(true);
      try { this.setMessage(this.msgKind, type, defs); } finally { Blockly.Events.setGroup(false); }
    }).catch(() => {});
  },
};

Blockly.Extensions.registerMutator('ros_message_mutator', MESSAGE_MIXIN, function () {
  const block = this;
  this.getField('TYPE').shortText = true;     // "Twist"; the menu and the tooltip give the full type
  // inside another message the field name says it all: no "message Vector3" label there
  this.setOnChange(function () {
    const nested = this.getParent()?.type === 'ros_message';
    if (nested === this.nested_) return;
    this.nested_ = nested;
    this.getField('KIND').setVisible(!nested);
    this.getField('TYPE').setVisible(!nested);
    this.queueRender?.();
  });
  this.setTooltip(() => t('msg.tooltip', { kind: LABEL[block.msgKind] ?? LABEL.msg, type: block.msgType }));
  this.getField('TYPE').setValidator(function (v) {
    if (typeof v === 'string' && !v.startsWith('\u0000')) setTimeout(() => block.onTypeChosen_(v), 0);
    return undefined;
  });
});
