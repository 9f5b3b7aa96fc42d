// A node's parameters through its own rcl_interfaces services, as `ros2 param` reads and sets them:
// list_parameters, then get_parameters and describe_parameters for the values and types, and
// set_parameters for a change. Whether a change is allowed is the gateway's to say (a viewer reads;
// a student sets her own station's nodes; an admin any): its refusal, or the node's own (a wrong
// type, a read-only parameter, a value out of its range), is shown beside the parameter.
import { t } from '../i18n.js';

export const TYPES = ['', 'bool', 'integer', 'double', 'string', 'byte[]', 'bool[]', 'integer[]', 'double[]', 'string[]'];
const FIELDS = [null, 'bool_value', 'integer_value', 'double_value', 'string_value', 'byte_array_value',
  'bool_array_value', 'integer_array_value', 'double_array_value', 'string_array_value'];

// A ParameterValue as the text its input shows, and back (null: the text is no value of that type).
export function valueText(v) {
  const x = v[FIELDS[v.type]];
  return v.type >= 5 ? JSON.stringify(Array.from(x ?? [])) : String(x ?? '');
}

export function parseValue(type, text) {
  const msg = { type };
  if (type === 1) msg.bool_value = text === 'true';
  else if (type === 2) { if (!/^-?\d+$/.test(text.trim())) return null; msg.integer_value = Number(text); }
  else if (type === 3) { const n = Number(text); if (text.trim() === '' || !Number.isFinite(n)) return null; msg.double_value = n; }
  else if (type === 4) msg.string_value = text;
  else if (type >= 5 && type <= 9) {
    let list;
    try { list = JSON.parse(text); } catch { return null; }
    if (!Array.isArray(list)) return null;
    if (type === 5) msg.byte_array_value = btoa(String.fromCharCode(...list.map((b) => b & 255)));
    else msg[FIELDS[type]] = list;
  } else return null;
  return msg;
}

export class Params {
  constructor(wire, els) {
    this.wire = wire;
    this.els = els;       // {root, body, info}
    this.node = '';
  }

  async show(node, services) {
    this.node = node;
    this.els.body.replaceChildren();
    this.els.root.dataset.node = node;
    this.els.root.dataset.params = '';
    if (!services.includes(`${node}/list_parameters`)) {
      this.els.info.textContent = t('inspect.params.none', { node });
      return;
    }
    this.els.info.textContent = t('inspect.params.loading');
    try {
      const { result } = await this.wire.call(`${node}/list_parameters`, { prefixes: [], depth: 0 });
      const names = result.names;
      const [{ values }, { descriptors }] = await Promise.all([
        this.wire.call(`${node}/get_parameters`, { names }),
        this.wire.call(`${node}/describe_parameters`, { names }).catch(() => ({ descriptors: [] }))]);
      if (node !== this.node) return;
      this.els.body.replaceChildren(...names.map((name, i) => this._row(name, values[i], descriptors[i])));
      this.els.info.textContent = t('inspect.params.count', { n: names.length });
      this.els.root.dataset.params = String(names.length);
    } catch (e) {
      this.els.info.textContent = t('inspect.params.failed', { error: e.message });
    }
  }

  _row(name, value, descriptor) {
    const tr = document.createElement('tr');
    tr.dataset.param = name;
    const cells = ['name', 'type', 'value', 'set'].map((c) => { const td = document.createElement('td'); td.className = c; tr.append(td); return td; });
    cells[0].textContent = name;
    if (descriptor?.description) cells[0].title = descriptor.description;
    cells[1].textContent = TYPES[value.type] ?? String(value.type);
    let input;
    if (value.type === 1) {
      input = document.createElement('select');
      input.append(new Option('true', 'true'), new Option('false', 'false'));
      input.value = String(value.bool_value);
    } else {
      input = document.createElement('input');
      input.value = valueText(value);
      if (value.type === 2 || value.type === 3) input.inputMode = 'decimal';
    }
    input.setAttribute('aria-label', name);
    input.disabled = Boolean(descriptor?.read_only);
    const button = document.createElement('button');
    button.type = 'button';
    button.textContent = t('inspect.params.set');
    button.disabled = input.disabled;
    const note = document.createElement('small');
    cells[2].append(input);
    cells[3].append(button, note);
    button.addEventListener('click', () => this.set(name, value.type, input.value, tr, note));
    return tr;
  }

  async set(name, type, text, tr, note) {
    const value = parseValue(type, text);
    tr.dataset.result = '';
    if (value === null) {
      note.textContent = t('inspect.params.bad', { type: TYPES[type] });
      tr.dataset.result = 'invalid';
      return;
    }
    try {
      const { results } = await this.wire.call(`${this.node}/set_parameters`, { parameters: [{ name, value }] },
        { type: 'rcl_interfaces/srv/SetParameters' });
      const r = results[0];
      note.textContent = r.successful ? t('inspect.params.done') : t('inspect.params.refused.node', { why: r.reason });
      tr.dataset.result = r.successful ? 'set' : 'refused';
    } catch (e) {
      note.textContent = t('inspect.refused', { why: e.message });
      tr.dataset.result = 'refused';
    }
  }
}
