// Turns the `rosgate` spec of a data-defined block (robot sets, "make a block") into code.
// A spec's values are templates:
//   "$NAME"          the block's input NAME (code) or field NAME (a literal)
//   "$NAME:i"        the i-th number in field NAME's value (e.g. a colour "255 0 0")
//   "/${NAME}/pose"  a string with an input or field spliced in
//   {"$mul": [a, b]}, {"$deg2rad": a}
// A `latest` spec with `pick` (a selector template, see runtime/util.js pick) reads the whole
// message and picks from it; `index` names the optional input of an 'item:' selector.
//   numbers, booleans, null, objects and arrays as themselves
// `lang` adapts the output to one language (see javascript.js and python.js).
// A spec with `namespaced` (the robot sets) puts its names in the robot namespace: rt.ns(name).

const WHOLE = /^\$([A-Za-z_][A-Za-z0-9_]*)(?::(\d+))?$/;
const SPLICE = /\$\{([A-Za-z_][A-Za-z0-9_]*)\}/g;

// A value: {code, lit} where lit is the constant it stands for, when known.
function inputValue(gen, block, name, lang) {
  if (block.getInput(name)) {
    const code = gen.valueToCode(block, name, lang.order.NONE);
    if (!code) return { code: lang.none, lit: null };
    const lit = lang.parseLiteral(code);
    return lit === undefined ? { code } : { code, lit };
  }
  const v = block.getFieldValue(name);
  if (v === null || v === undefined) throw new Error(`block ${block.type} has no input or field ${name}`);
  return constant(v, lang, true);
}

function constant(v, lang, fromField = false) {
  if (typeof v === 'number') return { code: lang.num(v), lit: v };
  if (typeof v === 'boolean') return { code: lang.bool(v), lit: v };
  if (v === null) return { code: lang.none, lit: null };
  if (fromField && /^-?\d+(\.\d+)?$/.test(v)) return { code: lang.num(Number(v)), lit: Number(v) };
  return { code: lang.str(v), lit: v };
}

export function value(gen, block, tpl, lang) {
  if (tpl === null || typeof tpl === 'number' || typeof tpl === 'boolean') return constant(tpl, lang);
  if (Array.isArray(tpl)) {
    const items = tpl.map((t) => value(gen, block, t, lang));
    return { code: lang.arr(items.map((i) => i.code)) };
  }
  if (typeof tpl === 'object') {
    if ('$mul' in tpl) {
      const [a, b] = tpl.$mul.map((t) => value(gen, block, t, lang));
      if (typeof a.lit === 'number' && typeof b.lit === 'number') return constant(a.lit * b.lit, lang);
      if (a.lit === 1) return b;
      if (a.lit === -1) return { code: lang.neg(b.code) };
      return { code: lang.mul(a.code, b.code) };
    }
    if ('$deg2rad' in tpl) {
      const a = value(gen, block, tpl.$deg2rad, lang);
      return { code: lang.deg2rad(a.code) };
    }
    const entries = Object.entries(tpl).map(([k, t]) => [k, value(gen, block, t, lang).code]);
    return { code: lang.obj(entries) };
  }
  const whole = WHOLE.exec(tpl);
  if (whole) {
    const [, name, index] = whole;
    if (index !== undefined) {
      const parts = String(block.getFieldValue(name)).trim().split(/\s+/);
      return constant(Number(parts[Number(index)]), lang);
    }
    return inputValue(gen, block, name, lang);
  }
  // string with ${NAME} splices: fold constants, concatenate the rest
  const parts = [];
  let last = 0;
  for (const m of tpl.matchAll(SPLICE)) {
    if (m.index > last) parts.push({ code: lang.str(tpl.slice(last, m.index)), lit: tpl.slice(last, m.index) });
    parts.push(inputValue(gen, block, m[1], lang));
    last = m.index + m[0].length;
  }
  if (last < tpl.length) parts.push({ code: lang.str(tpl.slice(last)), lit: tpl.slice(last) });
  if (parts.every((p) => p.lit !== undefined && p.lit !== null)) return constant(parts.map((p) => String(p.lit)).join(''), lang);
  return { code: lang.concat(parts) };
}

const v = (gen, block, tpl, lang) => value(gen, block, tpl, lang).code;

// Code for a spec'd block: a statement string, or [expression, order] for an output block.
export function specToCode(gen, block, spec, lang) {
  const isValue = !!block.outputConnection;
  const V = (t) => v(gen, block, t, lang);
  const N = (t) => (spec.namespaced ? lang.ns(V(t)) : V(t));    // a topic, service or action name
  const robotSpec = () => lang.obj([
    ['cmd', N(spec.cmd)], ['type', V(spec.type ?? 'geometry_msgs/msg/Twist')],
    ['pose', N(spec.pose)], ['pose_type', V(spec.pose_type)],
  ]);
  switch (spec.kind) {
    case 'publish':
      return lang.stmt('publish', [N(spec.topic), V(spec.type), V(spec.msg ?? {})], false);
    case 'drive':
      return lang.stmt('drive', [N(spec.topic), V(spec.type), V(spec.msg ?? {}), V(spec.seconds ?? 1)], true);
    case 'move':
      return lang.stmt('move', [robotSpec(), V(spec.distance), V(spec.speed ?? 1)], true);
    case 'turn':
      return lang.stmt('turn', [robotSpec(), V(spec.degrees), V(spec.speed ?? 90)], true);
    case 'call': {
      const args = [N(spec.service), V(spec.type), V(spec.args ?? {})];
      if (!isValue) return lang.stmt('callService', args, true);
      const call = lang.call('callService', args, true);
      return spec.field ? [lang.field(call, V(spec.field)), lang.order.CALL] : [call, lang.order.CALL];
    }
    case 'goal': {
      const args = [N(spec.action), V(spec.type), V(spec.args ?? {})];
      if (!isValue) return lang.stmt('sendGoal', args, true);
      return [lang.call('sendGoal', args, true), lang.order.CALL];
    }
    case 'latest': {
      const topic = N(spec.topic);
      const type = V(spec.type);
      if (spec.pick !== undefined) {     // "make a block" reader: a field or a reducer over a list
        const msg = lang.call('latest', [topic, type], true);
        const index = spec.index && block.getInput(spec.index) ? V(`$${spec.index}`) : lang.num(0);
        return [lang.helper('pick', [msg, V(spec.pick), index]), lang.order.CALL];
      }
      if (spec.fn === 'range_at') {
        const scan = lang.call('latest', [topic, type], true);
        const extra = (spec.fn_args ?? [0, 30]).map(V);
        return [lang.helper('rangeAt', [scan, ...extra]), lang.order.CALL];
      }
      const read = lang.call('latest', [topic, type, V(spec.field ?? '')], true);
      if (spec.fn === 'deg') return [lang.degrees(read), lang.order.CALL];
      if (spec.fn === 'yaw_deg') return [lang.degrees(lang.helper('yaw', [read])), lang.order.CALL];
      if (spec.fn === 'percent') return [lang.mul(read, '100'), lang.order.MUL];
      return [read, lang.order.CALL];
    }
    default:
      throw new Error(`unknown block spec kind '${spec.kind}' in ${block.type}`);
  }
}
