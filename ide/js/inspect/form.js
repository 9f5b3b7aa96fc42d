// A form built from a type's definition (rosapi's message_details / service_request_details
// typedefs): a nested fieldset per message field, a checkbox per bool, a number field per number
// (whole numbers for integer types), a text field per string, and a JSON field per array (`[1, 2]`,
// or `[{"x": 1}]` for an array of messages). value() reads it back as a message, or throws naming
// the field that holds no value of its type. The gateway checks the message again (its types,
// its rules) when it is published or sent.
import { t } from '../i18n.js';

const INTEGERS = new Set(['byte', 'char', 'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64']);
const FLOATS = new Set(['float32', 'float64']);

export class FormError extends Error {}

export class MessageForm {
  // typedefs: root first; el: the element the form is built in
  constructor(el, typedefs) {
    this.el = el;
    this.defs = new Map(typedefs.map((d) => [d.type, d]));
    this.controls = [];     // {path, kind, input, type}
    el.replaceChildren(this._fields(typedefs[0], []));
  }

  _fields(def, path) {
    const box = document.createElement('div');
    box.className = 'fields';
    def.fieldnames.forEach((name, i) => {
      const type = def.fieldtypes[i];
      const array = def.fieldarraylen[i] !== -1;
      const here = [...path, name];
      const nested = this.defs.get(type);
      if (nested && !array) {
        const set = document.createElement('fieldset');
        const legend = document.createElement('legend');
        legend.textContent = `${name} (${type})`;
        set.append(legend, this._fields(nested, here));
        box.append(set);
        return;
      }
      const label = document.createElement('label');
      const span = document.createElement('span');
      span.textContent = name;
      const input = document.createElement('input');
      input.name = here.join('.');
      let kind;
      if (array) {
        kind = 'json';
        input.value = def.examples[i] && def.examples[i] !== '{}' ? def.examples[i] : '[]';
        input.placeholder = nested ? '[{…}]' : '[1, 2, 3]';
      } else if (type === 'bool') {
        kind = 'bool';
        input.type = 'checkbox';
      } else if (INTEGERS.has(type) || FLOATS.has(type)) {
        kind = INTEGERS.has(type) ? 'int' : 'float';
        input.type = 'text';
        input.inputMode = kind === 'int' ? 'numeric' : 'decimal';
        input.value = def.examples[i] || '0';
      } else {
        kind = 'string';
        input.value = def.examples[i] ?? '';
      }
      const small = document.createElement('small');
      small.textContent = array ? `${type}[]` : type;
      label.append(span, input, small);
      box.append(label);
      this.controls.push({ path: here, kind, input, type });
    });
    return box;
  }

  // The message the form holds (throws FormError naming a field that holds none of its type).
  value() {
    const msg = {};
    for (const c of this.controls) {
      let v;
      const text = c.input.value.trim();
      if (c.kind === 'bool') v = c.input.checked;
      else if (c.kind === 'string') v = c.input.value;
      else if (c.kind === 'json') {
        try { v = JSON.parse(text || '[]'); } catch { v = undefined; }
        if (!Array.isArray(v)) this._bad(c);
      } else {
        v = Number(text);
        if (text === '' || !Number.isFinite(v) || (c.kind === 'int' && !Number.isInteger(v))) this._bad(c);
      }
      c.input.removeAttribute('aria-invalid');
      let box = msg;
      for (const key of c.path.slice(0, -1)) box = (box[key] ??= {});
      box[c.path.at(-1)] = v;
    }
    return msg;
  }

  _bad(c) {
    c.input.setAttribute('aria-invalid', 'true');
    c.input.focus();
    throw new FormError(t('inspect.form.bad', { field: c.path.join('.'), type: c.kind === 'json' ? `${c.type}[]` : c.type }));
  }
}
