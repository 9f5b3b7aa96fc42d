// A block program as a ROS 2 node, the way a ROS teacher writes one with rclpy: a Node subclass
// whose __init__ makes the publishers, subscriptions, clients, timers and servers the blocks
// name (typed: `self.create_publisher(Twist, 'cmd_vel', 10)`, `Twist(linear=Vector3(x=0.3))`);
// the main stack as `async def run(self)`, run by the executor as a task, so a waiting block
// (`await self.sleep(0.5)`, `await self.set_pen_client.call_async(request)`) lets the node's
// callbacks run meanwhile; "on message", "every" and the server blocks as callbacks; blocks with no
// rclpy counterpart (move until, turn by, drive for, range ahead) as small methods in the file.
// No runtime: the file needs rclpy and the message packages it imports, and runs unchanged in the
// page (runtime/browser/rclpy) and on a ROS 2 machine (generators/package.js makes its package).
//
// Names: a robot block's name, and a generic block's name in the robot namespace, is written
// relative ('cmd_vel'), so `--ros-args -r __ns:=/s07` puts the node on that robot; others as they
// are. Block variables are attributes of the node (self.speed).
/* global Blockly, python */
import { RosPythonGenerator, gen as pyGen, lang as pyLang } from './python.js';
import { specToCode } from './spec.js';
import { inServeAction, NAME_KINDS } from './scope.js';

const { Order } = python;
const I = '    ';

// ---- what a program's code uses (the package's dependencies) -----------------------------------
const FROM_IMPORT = /^from ([A-Za-z_]\w*)\.(?:msg|srv|action) import /gm;

// The ROS packages a node's (or any rclpy program's) imports name: rclpy and each message package.
export function rosUses(code) {
  const packages = new Set(['rclpy']);
  for (const m of code.matchAll(FROM_IMPORT)) packages.add(m[1]);
  return { packages: [...packages].sort() };
}

export const safeIdent = (s, fallback) => (String(s).toLowerCase().replace(/\W+/g, '_').replace(/^_+|_+$/g, '').replace(/^(\d)/, '_$1') || fallback);
const camel = (s) => s.split('_').map((w) => w.charAt(0).toUpperCase() + w.slice(1)).join('');
export const fullType = (t, kind = 'msg') => {
  const p = String(t || '').split('/');
  return p.length === 2 ? `${p[0]}/${kind}/${p[1]}` : String(t || '');
};

const FLOAT = /^(float(32|64)?|double)$/;
const INT = /^(u?int(8|16|32|64)|byte|char|octet)$/;
const NUMBER = /^-?\d+(\.\d+)?(e[+-]?\d+)?$/i;
const STRING = /^'(?:[^'\\]|\\.)*'$/;
const VELOCITY = /^geometry_msgs\/msg\/Twist(Stamped)?$/;

// A value of a field, coerced to the field's Python type as rclpy checks it (float for float64 ...).
function coerce(code, type, array = -1) {
  const base = String(type).replace(/<=\d+$/, '');
  if (array !== -1) return FLOAT.test(base) ? `[float(v) for v in ${code}]` : code;
  if (FLOAT.test(base)) {
    if (NUMBER.test(code)) return /[.e]/i.test(code) ? code : `${code}.0`;
    if (/^-?math\.(radians|degrees|sqrt|sin|cos|tan|atan2|hypot|fabs|exp|log|pi)\b/.test(code)) return code;   // a float already
    return `float(${code})`;
  }
  if (INT.test(base)) return /^-?\d+$/.test(code) ? code : `int(${code})`;
  if (base === 'bool' || base === 'boolean') return code === 'True' || code === 'False' ? code : `bool(${code})`;
  if (base === 'string' || base === 'wstring') return STRING.test(code) ? code : `str(${code})`;
  return code;
}

// A spec template's object (see spec.js value()): kept as a structure until its type is known.
class Struct {
  constructor(entries) { this.entries = entries; }
}

class RosNodeGenerator extends RosPythonGenerator {
  constructor() {
    super();
    this.forBlock = Object.create(pyGen.forBlock);   // Blockly's own blocks as the script writes them
    Object.assign(this.forBlock, NODE_BLOCKS);
    this.INDENT = I;
    this.addReservedWords('self,rclpy,Node,main,run,sleep,wait_for,next_message,call,send_goal,move,turn,drive,' +
      'velocity,stop_robot,elapsed,follow,publisher_for,to_message,range_at,yaw,pose_of,pick,field,math,time,signal,' +
      'Future,Duration,ActionClient,ActionServer,GoalStatus,SingleThreadedExecutor,SignalHandlerOptions,' +
      'ReentrantCallbackGroup,MutuallyExclusiveCallbackGroup,create_publisher,create_subscription,create_client,' +
      'create_service,create_timer,get_logger,get_clock,destroy_node,executor,GAIN');
    this.packageName = 'rosgate_program';
    this.nodeName = 'program';
    this.className = 'Program';
  }

  init(workspace) {
    super.init(workspace);
    this.locals_ = null;          // the variable ids that are a procedure's parameters (plain names)
    this.types_ = new Set();      // full type names the file imports
    this.ents_ = new Map();       // 'kind name' -> {kind, name, type, attr}
    this.methods_ = [];           // methods of the class, before run()
    this.callbacks_ = [];         // methods made for handler blocks
    this.inits_ = [];             // lines of __init__ after the entities
    this.helpers_ = new Set();    // helper methods and functions the code calls
    this.handlerCount_ = 0;       // handlers that keep the node running after run()
    this.awaitAny_ = false;
    this.usesActionServer_ = false;
    this.serving_ = null;
    this.missingTypes_ = new Set();   // 'kind:type' the generator would have typed with typedefs
    // block variables, but a procedure's parameters (its own names, not the node's attributes)
    const params = new Set(workspace.getAllBlocks(false).filter((b) => /^procedures_def/.test(b.type))
      .flatMap((b) => b.getVarModels().map((m) => m.getId())));
    this.vars_ = workspace.getVariableMap().getAllVariables().map((v) => v.getId()).filter((id) => !params.has(id));
    // the robot sets' and made blocks' specs, in this generator's words
    for (const [type, fn] of Object.entries(pyGen.forBlock)) {
      if (fn?.spec && !Object.prototype.hasOwnProperty.call(NODE_BLOCKS, type)) {
        this.forBlock[type] = (block, g) => specToCode(g, block, fn.spec, nodeLang);
      }
    }
  }

  getVariableName(id) {
    const name = super.getVariableName(id);
    return this.locals_?.has(id) ? name : `self.${name}`;
  }

  // ---- types and entities
  type(full) {
    this.types_.add(full);
    return this.alias(full);
  }

  alias(full) {
    const name = full.split('/')[2];
    const clash = [...this.types_].some((t) => t !== full && t.split('/')[2] === name);
    return clash ? camel(full.split('/')[0]) + name : name;
  }

  // A static name (a string literal) or null for a name computed at run time.
  static literal(code) {
    const v = pyLang.parseLiteral(code);
    return typeof v === 'string' ? v : null;
  }

  // The attribute of an entity with a static name, made once; its Python expression.
  entity(kind, name, type) {
    const key = `${kind} ${name.replace(/^\/+/, '')}`;
    let e = this.ents_.get(key);
    if (!e) {
      const used = new Set([...this.ents_.values()].map((x) => x.attr));
      const parts = name.split('/').filter(Boolean).map((p) => safeIdent(p, 'x'));
      const suffix = { pub: '_pub', sub: '', client: '_client', action: '_client' }[kind];
      let attr = '';
      for (let n = 1; n <= parts.length; n += 1) {
        attr = parts.slice(-n).join('_') + suffix;
        if (!used.has(attr) && !this.isReserved_(attr)) break;
      }
      while (used.has(attr) || this.isReserved_(attr)) attr += '_';
      e = { kind, name, type, attr, handlers: [] };
      this.ents_.set(key, e);
    } else if (!name.startsWith('/')) {
      e.name = name;          // written relative once: relative everywhere (one publisher, not two)
    }
    this.type(type);
    return e;
  }

  isReserved_(name) {
    return (this.RESERVED_WORDS_ ?? '').split(',').includes(name) || /^(sleep|run|call|move|turn|drive)$/.test(name);
  }

  // A publisher's Python expression: an attribute, or one made on first use for a computed name.
  publisher(nameCode, type) {
    const full = fullType(type);
    const name = RosNodeGenerator.literal(nameCode);
    if (name !== null) return `self.${this.entity('pub', name, full).attr}`;
    this.helpers_.add('publisher_for');
    return `self.publisher_for(${this.type(full)}, ${nameCode})`;
  }

  // A zero-argument function giving the newest message of a topic (None before the first).
  newest(nameCode, type) {
    const full = fullType(type);
    const name = RosNodeGenerator.literal(nameCode);
    if (name !== null) return `lambda: self.${this.entity('sub', name, full).attr}`;
    this.helpers_.add('follow');
    return `self.follow(${this.type(full)}, ${nameCode})`;
  }

  // The newest message of a topic as a value: the attribute (run() waits for the first one).
  latest(nameCode, type) {
    const full = fullType(type);
    const name = RosNodeGenerator.literal(nameCode);
    if (name !== null) {
      const e = this.entity('sub', name, full);
      e.read = true;
      return `self.${e.attr}`;
    }
    this.helpers_.add('follow').add('wait_for');
    return `(await self.newest(self.follow(${this.type(full)}, ${nameCode}), ${nameCode}))`;
  }

  client(kind, nameCode, type) {
    const full = fullType(type, kind === 'client' ? 'srv' : 'action');
    const name = RosNodeGenerator.literal(nameCode);
    if (name !== null) return `self.${this.entity(kind, name, full).attr}`;
    this.helpers_.add(`${kind}_for`);
    return `self.${kind}_for(${this.type(full)}, ${nameCode})`;
  }

  // ---- messages
  // A message of `full` type from a value: a typed constructor when its fields' types are known
  // (a message block, typedefs the page has read), else to_message() (fields converted by type).
  message(full, value, kind = 'msg') {
    if (value instanceof Struct) {
      const defs = this.typedefs(kind, full);
      if (defs) return this.construct(full, value, defs, kind);
      this.helpers_.add('to_message');
      return `to_message(${this.classOf(full, kind)}, ${this.dictCode(value)})`;
    }
    if (/^[A-Z]\w*(\.(Request|Goal|Result|Feedback|Response))?\(/.test(value)) return value;   // typed already
    this.helpers_.add('to_message');
    return `to_message(${this.classOf(full, kind)}, ${value || '{}'})`;
  }

  // The Python class expression of a type's part: Twist, SetPen.Request, Fibonacci.Goal.
  classOf(full, kind) {
    const part = { request: 'Request', response: 'Response', goal: 'Goal', result: 'Result', feedback: 'Feedback' }[kind];
    const cls = this.type(full);
    return part ? `${cls}.${part}` : cls;
  }

  typedefs(kind, full) {
    if (kind === 'msg' && VELOCITY.test(full)) return VELOCITY_DEFS[full];
    const defs = this.scope.types?.(kind, full);
    if (!defs) this.missingTypes_.add(`${kind}:${full}`);
    return defs;
  }

  construct(full, struct, defs, kind) {
    const byType = new Map(defs.map((d) => [fullType(d.type), d]));
    const build = (cls, def, st) => {
      const args = [];
      for (const [k, v] of st.entries) {
        const i = def.fieldnames.indexOf(k);
        if (i < 0) throw new Error(`${def.type} has no field '${k}'`);
        const ft = def.fieldtypes[i];
        if (v instanceof Struct) {
          const sub = fullType(ft);
          args.push(`${k}=${build(this.type(sub), byType.get(sub) ?? { fieldnames: [], fieldtypes: [] }, v)}`);
        } else {
          args.push(`${k}=${coerce(v, ft, def.fieldarraylen[i])}`);
        }
      }
      return `${cls}(${args.join(', ')})`;
    };
    return build(this.classOf(full, kind), defs[0], struct);
  }

  // A publish: `msg = Twist()`, a line for each field that is not zero, then the publish.
  publishCode(pub, full, value) {
    const lines = value instanceof Struct ? this.assignments(full, value) : null;
    if (lines === null) return `${pub}.publish(${this.message(full, value)})\n`;
    const cls = this.type(full);
    if (!lines.length) return `${pub}.publish(${cls}())\n`;
    return `msg = ${cls}()\n${lines.map((l) => `${l}\n`).join('')}${pub}.publish(msg)\n`;
  }

  // `msg.linear.x = 0.3` lines of a template's fields (zeros left out: they are the defaults), or
  // null when the type's fields are not known.
  assignments(full, struct, kind = 'msg') {
    const defs = struct.fields ? null : this.typedefs(kind, full);
    if (!struct.fields && !defs) return null;
    const byType = new Map((defs ?? []).map((d) => [fullType(d.type), d]));
    const fieldsOf = (def, st) => (st.fields
      ? st.fields
      : (def?.fieldnames ?? []).map((name, i) => ({ name, type: def.fieldtypes[i], array: def.fieldarraylen[i] })));
    const out = [];
    const walk = (def, st, path) => {
      const fields = fieldsOf(def, st);
      for (const [k, v] of st.entries) {
        const f = fields.find((x) => x.name === k);
        if (!f) throw new Error(`${def?.type ?? full} has no field '${k}'`);
        if (v instanceof Struct) walk(byType.get(fullType(f.type)), v, `${path}.${k}`);
        else if (!/^(-?0(\.0*)?|False|''|None)$/.test(v)) out.push(`${path}.${k} = ${coerce(v, f.type, f.array)}`);
      }
    };
    walk(defs?.[0], struct, 'msg');
    return out;
  }

  dictCode(v) {
    if (v instanceof Struct) return `{${v.entries.map(([k, c]) => `${this.quote_(k)}: ${this.dictCode(c)}`).join(', ')}}`;
    return v;
  }

  // ---- methods
  // A method of the class; async when its body waits (it holds an await).
  method(name, params, body, { doc = '', forceAsync = false } = {}) {
    const isAsync = forceAsync || /\bawait\b/.test(body);
    if (isAsync) this.awaitAny_ = true;
    const docLine = doc ? `${I}"""${doc}"""\n` : '';
    const text = `${isAsync ? 'async ' : ''}def ${name}(${['self', ...params].join(', ')}):\n${docLine}${body || (doc ? '' : this.PASS)}`;
    return { name, isAsync, text };
  }

  callbackName(prefix) {
    return this.nameDB_.getDistinctName(prefix, Blockly.Names.NameType.PROCEDURE);
  }

  finish(code) {
    const imports = [];
    const defs = [];
    for (const [key, def] of Object.entries(this.definitions_)) {
      if (key === 'variables') continue;                 // block variables are the node's attributes
      if (/^(from\s+\S+\s+)?import\s+\S+/.test(def)) imports.push(def); else defs.push(def);
    }
    const body = this.prefixLines(code, I);
    this.varNames_ = this.vars_.map((id) => this.getVariableName(id));
    Blockly.CodeGenerator.prototype.finish.call(this, code);
    this.isInitialized = false;
    this.nameDB_.reset();
    return this.compose(imports, defs, body);
  }
}

// Twist and TwistStamped, known here: the robot blocks' messages type without asking the gateway.
const VECTOR3 = { type: 'geometry_msgs/Vector3', fieldnames: ['x', 'y', 'z'], fieldtypes: ['float64', 'float64', 'float64'], fieldarraylen: [-1, -1, -1] };
const TWIST = { type: 'geometry_msgs/Twist', fieldnames: ['linear', 'angular'], fieldtypes: ['geometry_msgs/Vector3', 'geometry_msgs/Vector3'], fieldarraylen: [-1, -1] };
const VELOCITY_DEFS = {
  'geometry_msgs/msg/Twist': [TWIST, VECTOR3],
  'geometry_msgs/msg/TwistStamped': [{ type: 'geometry_msgs/TwistStamped', fieldnames: ['header', 'twist'], fieldtypes: ['std_msgs/Header', 'geometry_msgs/Twist'], fieldarraylen: [-1, -1] },
    { type: 'std_msgs/Header', fieldnames: ['frame_id'], fieldtypes: ['string'], fieldarraylen: [-1] }, TWIST, VECTOR3],
};

// ---- the parts of the file -------------------------------------------------------------------------
RosNodeGenerator.prototype.compose = function compose(imports, defs, body) {
  const g = this;
  const cls = g.className;
  const ents = [...g.ents_.values()];
  const has = (h) => g.helpers_.has(h);
  if (has('move') || has('turn') || has('drive')) g.helpers_.add('velocity').add('sleep');
  if (has('move') || has('turn')) g.helpers_.add('wait_for').add('pose_of');
  if (has('wait_for') || has('next_message')) g.helpers_.add('sleep').add('wait_for');
  if (has('pose_of') || has('range_at')) g.helpers_.add('yaw');
  if (has('follow')) g.helpers_.add('newest');
  const reads = ents.filter((e) => e.kind === 'sub' && e.read);
  if (reads.length) g.helpers_.add('wait_for').add('sleep');
  const velocity = ents.filter((e) => e.kind === 'pub' && VELOCITY.test(e.type));
  // a callback that waits (async) holds its callback group until it ends: then every entity is in
  // one reentrant group (what it waits for goes on), and a timer or subscription whose callback
  // waits in a group of its own (it does not overlap itself)
  const group = g.callbacks_.some((c) => c.isAsync) || ents.some((e) => e.handlers.some((h) => h.isAsync));
  g.group_ = group;
  const inGroup = group ? ', callback_group=self.group' : '';

  // __init__
  const init = [`super().__init__(${g.quote_(g.nodeName)})`];
  if (group) init.push('self.group = ReentrantCallbackGroup()  # callbacks that wait let the others run meanwhile');
  if (has('elapsed')) init.push('self.start_time = self.get_clock().now()');
  for (const name of g.varNames_) init.push(`${name} = None`);
  for (const e of ents.filter((x) => x.kind === 'pub')) {
    init.push(`self.${e.attr} = self.create_publisher(${g.alias(e.type)}, ${g.quote_(e.name)}, 10)`);
  }
  if (velocity.length || has('publisher_for')) {
    init.push(`self.velocity_publishers = [${velocity.map((e) => `self.${e.attr}`).join(', ')}]  # stop_robot() zeroes them`);
  }
  const subCallbacks = [];
  for (const e of ents.filter((x) => x.kind === 'sub')) {
    const cb = `on_${e.attr}`;
    init.push(`self.${e.attr} = None  # the newest message on ${e.name}`);
    const own = e.handlers.find((h) => h.isAsync) ? 'MutuallyExclusiveCallbackGroup()' : null;
    init.push(`self.create_subscription(${g.alias(e.type)}, ${g.quote_(e.name)}, self.${cb}, 10${own ? `, callback_group=${own}` : inGroup})`);
    const lines = [`${I}self.${e.attr} = msg\n`, ...e.handlers.map((h) => h.body)].join('');
    subCallbacks.push(g.method(cb, ['msg'], lines));
  }
  for (const e of ents.filter((x) => x.kind === 'client')) {
    init.push(`self.${e.attr} = self.create_client(${g.alias(e.type)}, ${g.quote_(e.name)}${inGroup})`);
  }
  for (const e of ents.filter((x) => x.kind === 'action')) {
    init.push(`self.${e.attr} = ActionClient(self, ${g.alias(e.type)}, ${g.quote_(e.name)}${inGroup})`);
  }
  if (has('follow')) init.push('self.followed = {}  # topic -> its newest message (follow())');
  if (has('publisher_for')) init.push('self.made_publishers = {}  # topic -> its publisher (publisher_for())');
  if (has('client_for')) init.push('self.made_clients = {}  # service -> its client (client_for())');
  if (has('action_for')) init.push('self.made_action_clients = {}  # action -> its client (action_for())');
  init.push(...new Set(g.inits_.map((l) => l.replace('${group}', inGroup))));

  const methods = [];
  methods.push(`def __init__(self):\n${init.map((l) => I + l).join('\n')}\n`);
  const firsts = reads.map((e) => `${I}await self.wait_for(lambda: self.${e.attr} is not None, 'a message on ${e.name.replace(/'/g, '')}')\n`).join('');
  const run = g.method('run', [], `${firsts}${body.trim() ? body : ''}`, {
    doc: 'The program\'s blocks, in order: each await lets the node\'s callbacks run meanwhile.', forceAsync: true });
  if (!body.trim() && !firsts) run.text += `${I}pass\n`;
  methods.push(run.text);
  for (const m of [...subCallbacks, ...g.callbacks_, ...g.methods_]) methods.push(m.text);
  methods.push(...helperMethods(g));

  // imports
  const lines = [];
  const std = new Set(imports.map((i) => i.trim()));
  const needMath = /\bmath\./.test(methods.join('\n') + defs.join('\n'));
  if (needMath) std.add('import math');
  if (has('wait_for') || has('elapsed')) std.add('import time');
  std.add('import signal');
  const stdLines = [...std].filter((l) => /^import \w+$/.test(l)).sort();
  const otherStd = [...std].filter((l) => !/^import \w+$/.test(l));
  lines.push(...stdLines, ...otherStd, '');
  lines.push('import rclpy');
  const actions = [...(ents.some((e) => e.kind === 'action') || has('action_for') ? ['ActionClient'] : []), ...(g.usesActionServer_ ? ['ActionServer'] : [])];
  if (actions.length) lines.push(`from rclpy.action import ${actions.join(', ')}`);
  const groups = [...(group ? ['ReentrantCallbackGroup'] : []), ...(/MutuallyExclusiveCallbackGroup/.test(methods.join('\n') + init.join('\n')) ? ['MutuallyExclusiveCallbackGroup'] : [])];
  if (groups.length) lines.push(`from rclpy.callback_groups import ${groups.join(', ')}`);
  if (velocity.length || has('publisher_for')) lines.push('from rclpy.duration import Duration');
  lines.push('from rclpy.executors import SingleThreadedExecutor');
  lines.push('from rclpy.node import Node');
  lines.push('from rclpy.signals import SignalHandlerOptions');
  if (has('sleep')) lines.push('from rclpy.task import Future');
  if (has('send_goal')) g.types_.add('action_msgs/msg/GoalStatus');
  const typeLines = [];
  for (const t of [...g.types_].sort()) {
    const [pkg, kind, name] = t.split('/');
    const as = g.alias(t);
    typeLines.push(`from ${pkg}.${kind} import ${name}${as === name ? '' : ` as ${as}`}`);
  }
  if (typeLines.length) lines.push('', ...new Set(typeLines));

  const functions = [...defs.map((d) => d.trim()), ...helperFunctions(g)].filter(Boolean);
  const handlers = g.handlerCount_ > 0;
  const main = [
    'def main(args=None):',
    `${I}# Ctrl-C is this node's to handle: it stops the robot before ROS shuts down`,
    `${I}rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)`,
    `${I}signal.signal(signal.SIGTERM, signal.default_int_handler)  # a stop request, as Ctrl-C`,
    `${I}node = ${cls}()`,
    `${I}executor = SingleThreadedExecutor()`,
    `${I}executor.add_node(node)`,
    `${I}program = executor.create_task(node.run)`,
    `${I}try:`,
    `${I}${I}while rclpy.ok() and not program.done():  # short steps: Ctrl-C is seen at once`,
    `${I}${I}${I}executor.spin_once(timeout_sec=0.1)`,
    `${I}${I}program.result()  # the program's error, if it had one`,
    ...(handlers ? [
      `${I}${I}node.get_logger().info('the program has run; its callbacks go on until Ctrl-C')`,
      `${I}${I}while rclpy.ok():`,
      `${I}${I}${I}executor.spin_once(timeout_sec=0.1)`] : []),
    `${I}except KeyboardInterrupt:`,
    `${I}${I}pass`,
    `${I}finally:`,
    ...(velocity.length || has('publisher_for') ? [`${I}${I}node.stop_robot()`] : []),
    `${I}${I}node.destroy_node()`,
    `${I}${I}rclpy.try_shutdown()`,
  ].join('\n');

  const doc = `"""${g.programName.replace(/"""/g, "'''")}: a block program of the rosgate IDE as a ROS 2 node (rclpy).\n\n` +
    `In a colcon workspace (its package in src/):\n${I}colcon build && source install/setup.bash\n` +
    `${I}ros2 run ${g.packageName} ${g.nodeName}${g.namespace ? '' : ' [--ros-args -r __ns:=/s07]'}\n` +
    'Ctrl-C stops the program and the robot.\n"""';
  const classText = `class ${cls}(Node):\n\n${methods.map((m) => indent(m.trimEnd())).join('\n\n')}\n`;
  return [doc, lines.join('\n'), ...functions, classText.trimEnd(), main, `if __name__ == '__main__':\n${I}main()`]
    .join('\n\n\n') + '\n';
};

const indent = (text) => text.split('\n').map((l) => (l ? I + l : l)).join('\n');

function helperMethods(g) {
  const has = (h) => g.helpers_.has(h);
  const out = [];
  if (has('sleep')) {
    out.push(`async def sleep(self, seconds):
    """Waits \`seconds\` while the node's callbacks go on (a one-shot timer wakes it)."""
    woken = Future()

    def wake():
        timer.cancel()
        woken.set_result(True)
    timer = self.create_timer(max(0.001, float(seconds)), wake${g.group_ ? ', callback_group=self.group' : ''})
    await woken
    self.destroy_timer(timer)`);
  }
  if (has('wait_for')) {
    out.push(`async def wait_for(self, ready, what, timeout=10.0):
    """Waits until ready() is true (an error after \`timeout\` s; None: no limit)."""
    end = None if timeout is None else time.monotonic() + timeout
    while not ready():
        if end is not None and time.monotonic() > end:
            raise TimeoutError(f'no {what} within {timeout:g} s')
        await self.sleep(0.02)`);
  }
  if (has('next_message')) {
    out.push(`async def next_message(self, newest, what, timeout=0):
    """The next message on a topic (newest() gives the newest one so far)."""
    before = newest()
    await self.wait_for(lambda: newest() is not before, f'message on {what}', float(timeout) or None)
    return newest()`);
  }
  if (has('newest')) {
    out.push(`async def newest(self, newest, what):
    """The newest message on a topic, once there is one."""
    await self.wait_for(lambda: newest() is not None, f'message on {what}')
    return newest()`);
  }
  if (has('follow')) {
    out.push(`def follow(self, msg_type, topic):
    """Subscribes to \`topic\` (once); a function giving its newest message (None before the first)."""
    if topic not in self.followed:
        self.followed[topic] = None

        def keep(msg):
            self.followed[topic] = msg
        self.create_subscription(msg_type, topic, keep, 10${g.group_ ? ', callback_group=self.group' : ''})
    return lambda: self.followed[topic]`);
  }
  if (has('publisher_for')) {
    out.push(`def publisher_for(self, msg_type, topic):
    """The publisher of \`topic\` (made at its first use)."""
    if topic not in self.made_publishers:
        self.made_publishers[topic] = self.create_publisher(msg_type, topic, 10)
        if msg_type.__name__ in ('Twist', 'TwistStamped'):
            self.velocity_publishers.append(self.made_publishers[topic])
    return self.made_publishers[topic]`);
  }
  if (has('client_for')) {
    out.push(`def client_for(self, srv_type, name):
    """The client of service \`name\` (made at its first use)."""
    if name not in self.made_clients:
        self.made_clients[name] = self.create_client(srv_type, name${g.group_ ? ', callback_group=self.group' : ''})
    return self.made_clients[name]`);
  }
  if (has('action_for')) {
    out.push(`def action_for(self, action_type, name):
    """The action client of \`name\` (made at its first use)."""
    if name not in self.made_action_clients:
        self.made_action_clients[name] = ActionClient(self, action_type, name${g.group_ ? ', callback_group=self.group' : ''})
    return self.made_action_clients[name]`);
  }
  if (has('call')) {
    out.push(`async def call(self, client, request):
    """Calls a service (it has 10 s to appear) and waits for its response."""
    if not client.wait_for_service(timeout_sec=10.0):
        raise RuntimeError(f'service {client.srv_name} is not available')
    return await client.call_async(request)`);
  }
  if (has('send_goal')) {
    out.push(`async def send_goal(self, client, goal, on_feedback=None):
    """Sends a goal to an action server, waits for its result and returns it; on_feedback(feedback)
    gets each feedback on the way."""
    if not client.wait_for_server(timeout_sec=10.0):
        raise RuntimeError('the action server is not available')
    feedback = None if on_feedback is None else (lambda message: on_feedback(message.feedback))
    goal_handle = await client.send_goal_async(goal, feedback_callback=feedback)
    if not goal_handle.accepted:
        raise RuntimeError('the action server refused the goal')
    self.goals.append(goal_handle)
    response = await goal_handle.get_result_async()
    self.goals.remove(goal_handle)
    if response.status != GoalStatus.STATUS_SUCCEEDED:
        raise RuntimeError(f'the goal ended with status {response.status}')
    return response.result`);
  }
  if (has('cancel')) {
    out.push(`def cancel_goals(self):
    """Cancels the goals this node is waiting for."""
    for goal_handle in list(self.goals):
        goal_handle.cancel_goal_async()`);
  }
  if (has('velocity')) {
    out.push(`def velocity(self, publisher, linear, angular):
    """Publishes a velocity command: \`linear\` m/s ahead, \`angular\` rad/s to the left."""
    msg = publisher.msg_type()
    twist = msg.twist if hasattr(msg, 'twist') else msg  # a TwistStamped holds a Twist
    twist.linear.x = float(linear)
    twist.angular.z = float(angular)
    publisher.publish(msg)`);
  }
  if (has('drive')) {
    out.push(`async def drive(self, publisher, msg, seconds):
    """Sends \`msg\` every 0.1 s for \`seconds\` s, then zero velocity."""
    end = time.monotonic() + max(0.0, float(seconds))
    while time.monotonic() < end:
        publisher.publish(msg)
        await self.sleep(min(0.1, max(0.0, end - time.monotonic())))
    publisher.publish(publisher.msg_type())`);
    g.helpers_.add('wait_for');
  }
  if (has('move')) {
    out.push(`async def move(self, publisher, pose, distance, speed=1.0):
    """Drives \`distance\` m straight on (back when negative) at up to \`speed\` m/s, slowing down near
    the end, and stops there; pose() gives the robot's newest pose."""
    await self.wait_for(lambda: pose() is not None, 'pose')
    x0, y0, _ = pose_of(pose())
    while True:
        x, y, _ = pose_of(pose())
        remaining = abs(distance) - math.hypot(x - x0, y - y0)
        if remaining <= 0.01:
            break
        self.velocity(publisher, math.copysign(max(0.1, min(speed, GAIN * remaining)), distance), 0.0)
        await self.sleep(0.02)
    self.velocity(publisher, 0.0, 0.0)`);
  }
  if (has('turn')) {
    out.push(`async def turn(self, publisher, pose, degrees, speed=90.0):
    """Turns \`degrees\` to the left (right when negative) at up to \`speed\` degrees/s, slowing down
    near the end, and stops there; pose() gives the robot's newest pose."""
    await self.wait_for(lambda: pose() is not None, 'pose')
    target, rate = math.radians(degrees), math.radians(speed)
    last = pose_of(pose())[2]
    turned = 0.0
    while True:
        heading = pose_of(pose())[2]
        turned += math.remainder(heading - last, 2 * math.pi)
        last = heading
        remaining = target - turned
        if math.copysign(1.0, target) * remaining <= 0.005:   # there, or just past it: no hunting
            break
        self.velocity(publisher, 0.0, math.copysign(max(0.1, min(rate, GAIN * abs(remaining))), target))
        await self.sleep(0.02)
    self.velocity(publisher, 0.0, 0.0)`);
  }
  if (has('elapsed')) {
    out.push(`def elapsed(self):
    """Seconds since the node started."""
    return (self.get_clock().now() - self.start_time).nanoseconds / 1e9`);
  }
  if (g.ents_.size && [...g.ents_.values()].some((e) => e.kind === 'pub' && VELOCITY.test(e.type)) || has('publisher_for')) {
    out.push(`def stop_robot(self):
    """Zero velocity on every velocity topic the program drives (at most 2 s for it to arrive)."""
    for publisher in self.velocity_publishers:
        publisher.publish(publisher.msg_type())
        publisher.wait_for_all_acked(Duration(seconds=2))`);
  }
  return out;
}

function helperFunctions(g) {
  const has = (h) => g.helpers_.has(h);
  const out = [];
  if (has('move') || has('turn')) out.push('GAIN = 6.0  # 1/s: how sharply move and turn slow down near the end');
  if (has('to_message')) {
    out.push(`def to_message(msg_type, values):
    """A message of msg_type from a dict of its fields (numbers converted to the fields' types)."""
    if isinstance(values, msg_type):
        return values
    msg = msg_type()
    for name, value in values.items():
        current = getattr(msg, name)
        if hasattr(current, 'get_fields_and_field_types'):
            value = to_message(type(current), value)
        elif isinstance(current, float):
            value = float(value)
        elif isinstance(current, bool):
            value = bool(value)
        elif isinstance(current, int):
            value = int(value)
        setattr(msg, name, value)
    return msg`);
  }
  if (has('yaw')) {
    out.push(`def yaw(q):
    """The heading (radians, to the left of x) of a geometry_msgs/Quaternion."""
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))`);
  }
  if (has('pose_of')) {
    out.push(`def pose_of(msg):
    """(x, y, heading) of a turtlesim/Pose or a nav_msgs/Odometry."""
    if hasattr(msg, 'theta'):
        return msg.x, msg.y, msg.theta
    pose = msg.pose.pose
    return pose.position.x, pose.position.y, yaw(pose.orientation)`);
  }
  if (has('range_at')) {
    out.push(`def range_at(scan, degrees=0.0, window=20.0):
    """The nearest valid range of a LaserScan within window/2 degrees of \`degrees\` (0 ahead, 90 left)."""
    centre, half = math.radians(degrees), math.radians(abs(window)) / 2
    best = math.inf
    for i, r in enumerate(scan.ranges):
        if not math.isfinite(r) or r < scan.range_min or r > scan.range_max:
            continue
        angle = scan.angle_min + i * scan.angle_increment
        if abs(math.remainder(angle - centre, 2 * math.pi)) <= half and r < best:
            best = r
    return best`);
  }
  if (has('pick')) {
    out.push(`def pick(msg, selector, index=0):
    """One value of a message: a field path ('pose.x'), or 'min:PATH', 'max:PATH', 'mean:PATH' of the
    finite numbers of a list field, or 'item:PATH' (item \`index\`)."""
    how, _, path = selector.rpartition(':')
    value = field(msg, path)
    if how == 'item':
        return value[int(index)]
    numbers = [v for v in value if isinstance(v, (int, float)) and math.isfinite(v)]
    if how == 'min':
        return min(numbers, default=math.inf)
    if how == 'max':
        return max(numbers, default=-math.inf)
    if how == 'mean':
        return sum(numbers) / len(numbers) if numbers else math.nan
    return value`);
    g.helpers_.add('field');
  }
  if (has('field')) {
    out.push(`def field(msg, path):
    """A field of a message by its path: field(odom, 'pose.pose.position.x'); numbers index lists."""
    for part in [p for p in str(path).split('.') if p]:
        msg = msg[int(part)] if part.lstrip('-').isdigit() else getattr(msg, part)
    return msg`);
  }
  return out;
}

// `(await x())` as `await x()` where the parentheses hold the whole of it.
function unwrap(code) {
  if (!code.startsWith('(') || !code.endsWith(')')) return code;
  let depth = 0;
  for (let i = 0; i < code.length; i += 1) {
    if (code[i] === '(') depth += 1;
    else if (code[i] === ')') depth -= 1;
    if (depth === 0 && i < code.length - 1) return code;      // closes before the end: (a) + (b)
  }
  return code.slice(1, -1);
}

// A field path as Python: 'pose.pose.position.x' -> .pose.pose.position.x, 'ranges.0' -> .ranges[0].
function pathCode(path) {
  return String(path).split('.').filter(Boolean).map((p) => (/^-?\d+$/.test(p) ? `[${p}]` : `.${p}`)).join('');
}

// A message block's fields as a template (the values' code), for publishCode's lines; the block's
// own field list gives the types, so no typedef is needed.
function messageStruct(g, block) {
  const entries = [];
  for (const f of block.msgFields) {
    const sub = block.getInputTargetBlock(`F_${f.name}`);
    if (sub?.type === 'ros_message' && f.array === -1) entries.push([f.name, messageStruct(g, sub)]);
    else {
      const code = g.valueToCode(block, `F_${f.name}`, Order.NONE);
      if (code) entries.push([f.name, code]);
    }
  }
  const st = new Struct(entries);
  st.fields = block.msgFields;
  st.sub = Object.fromEntries(block.msgFields.map((f) => [f.name, block.getInputTargetBlock(`F_${f.name}`)]));
  return st;
}

// Which part of its type a message block is: its own kind (a service's request ...), or, for a
// message block of a service or action type, the part its place asks for (a served service's answer
// is the Response).
const PART_KIND = { request: 'srv', response: 'srv', goal: 'action', result: 'action', feedback: 'action' };
const PLACE = {
  'ros_serve_service RESPONSE': 'response', 'ros_serve_action RESULT': 'result', 'ros_action_feedback VALUE': 'feedback',
  'ros_call_service REQUEST': 'request', 'ros_call_service_stmt REQUEST': 'request', 'ros_send_goal GOAL': 'goal',
};
function partOf(block) {
  if (block.msgKind && block.msgKind !== 'msg') return block.msgKind;
  const type = String(block.msgType || '');
  if (!/\/(srv|action)\//.test(type)) return 'msg';
  const parent = block.getParent();
  const input = block.outputConnection?.targetConnection?.getParentInput?.()?.name;
  return PLACE[`${parent?.type} ${input}`] ?? (type.includes('/srv/') ? 'request' : 'goal');
}

const nameOf = (g, block, field) => {
  const name = block.getFieldValue(field) ?? '';
  const relative = g.scope.inNamespace(NAME_KINDS[field], name);
  return g.quote_(relative ? name.replace(/^\/+/, '') || '/' : name);
};
const typeOf = (block) => block.getFieldValue('TYPE') || '';

// ---- the ROS blocks, as a node ----------------------------------------------------------------------
const NODE_BLOCKS = {
  ros_publish(block, g) {
    const full = fullType(typeOf(block));
    const pub = g.publisher(nameOf(g, block, 'TOPIC'), full);
    const msgBlock = block.getInputTargetBlock('MSG');
    if (msgBlock?.type === 'ros_message' && fullType(msgBlock.msgType) === full) {
      return g.publishCode(pub, full, messageStruct(g, msgBlock));
    }
    return `${pub}.publish(${g.message(full, g.valueToCode(block, 'MSG', Order.NONE))})\n`;
  },

  // a message block: its type's constructor, each field as rclpy checks it
  ros_message(block, g) {
    const nested = block.getParent()?.type === 'ros_message';
    const kind = nested ? 'msg' : partOf(block);
    const type = block.msgType || block.getFieldValue('TYPE') || '';
    const full = fullType(type, PART_KIND[kind] ?? 'msg');
    const cls = kind === 'msg' ? g.type(full) : g.classOf(full, kind);
    const args = [];
    for (const f of block.msgFields) {
      const code = g.valueToCode(block, `F_${f.name}`, Order.NONE);
      if (code) args.push(`${f.name}=${coerce(code, f.type, f.array)}`);
    }
    return [`${cls}(${args.join(', ')})`, Order.FUNCTION_CALL];
  },

  ros_on_message(block, g) {
    const v = g.getVariableName(block.getFieldValue('VAR'));
    const e = g.entity('sub', RosNodeGenerator.literal(nameOf(g, block, 'TOPIC')), fullType(typeOf(block)));
    const body = g.statementToCode(block, 'DO');
    e.handlers.push({ body: `${I}${v} = msg\n${body}`, isAsync: /\bawait\b/.test(body) });
    g.handlerCount_ += 1;
    return '';
  },

  ros_latest(block, g) {
    const msg = g.latest(nameOf(g, block, 'TOPIC'), typeOf(block));
    const path = block.getFieldValue('FIELD') || '';
    return [`${msg}${pathCode(path)}`, Order.MEMBER];
  },

  ros_wait_message(block, g) {
    g.helpers_.add('next_message');
    const name = nameOf(g, block, 'TOPIC');
    return `await self.next_message(${g.newest(name, typeOf(block))}, ${name})\n`;
  },

  ros_next_message(block, g) {
    g.helpers_.add('next_message');
    const name = nameOf(g, block, 'TOPIC');
    const timeout = g.valueToCode(block, 'TIMEOUT', Order.NONE) || '0';
    return [`(await self.next_message(${g.newest(name, typeOf(block))}, ${name}, ${timeout}))`, Order.ATOMIC];
  },

  ros_call_service(block, g) {
    g.helpers_.add('call');
    const full = fullType(typeOf(block), 'srv');
    const client = g.client('client', nameOf(g, block, 'SERVICE'), full);
    const request = g.message(full, g.valueToCode(block, 'REQUEST', Order.NONE), 'request');
    return [`(await self.call(${client}, ${request}))`, Order.ATOMIC];
  },

  ros_call_service_stmt(block, g) {
    const [code] = NODE_BLOCKS.ros_call_service(block, g);
    return `${code.slice(1, -1)}\n`;      // (await ...) as a statement: without its parentheses
  },

  ros_send_goal(block, g) {
    g.helpers_.add('send_goal');
    g.inits_.push('self.goals = []  # the goals sent and not done (cancel_goals())');
    const full = fullType(typeOf(block), 'action');
    const client = g.client('action', nameOf(g, block, 'ACTION'), full);
    const fbVar = g.getVariableName(block.getFieldValue('FEEDBACK_VAR'));
    const resVar = g.getVariableName(block.getFieldValue('RESULT_VAR'));
    const fbBody = g.statementToCode(block, 'FEEDBACK');
    let onFeedback = 'None';
    if (fbBody) {
      const name = g.callbackName('on_feedback');
      const m = g.method(name, ['feedback'], `${I}${fbVar} = feedback\n${fbBody}`);
      if (m.isAsync) {      // rclpy calls a feedback callback as it is: one that waits runs as a task
        onFeedback = `lambda feedback: self.executor.create_task(self.${name}, feedback)`;
      } else onFeedback = `self.${name}`;
      g.callbacks_.push(m);
    }
    const goal = g.message(full, g.valueToCode(block, 'GOAL', Order.NONE), 'goal');
    return `${resVar} = await self.send_goal(${client}, ${goal}${onFeedback === 'None' ? '' : `, ${onFeedback}`})\n` +
      g.statementToCode(block, 'RESULT').replace(new RegExp(`^${I}`, 'gm'), '');
  },

  ros_every(block, g) {
    const name = g.callbackName('every_tick');
    const seconds = g.valueToCode(block, 'SECONDS', Order.NONE) || '1';
    const m = g.method(name, [], g.statementToCode(block, 'DO') || g.PASS);
    g.callbacks_.push(m);
    g.inits_.push(`self.create_timer(${seconds}, self.${name}${m.isAsync ? ', callback_group=MutuallyExclusiveCallbackGroup()' : '${group}'})`);
    g.handlerCount_ += 1;
    return '';
  },

  ros_serve_service(block, g) {
    const full = fullType(typeOf(block), 'srv');
    const v = g.getVariableName(block.getFieldValue('VAR'));
    const name = g.callbackName('on_call');
    const body = g.statementToCode(block, 'DO');
    const answer = g.message(full, g.valueToCode(block, 'RESPONSE', Order.NONE) || '{}', 'response');
    const m = g.method(name, ['request', 'response'], `${I}${v} = request\n${body}${I}return ${answer}\n`);
    g.callbacks_.push(m);
    g.inits_.push(`self.create_service(${g.type(full)}, ${nameOf(g, block, 'SERVICE')}, self.${name}\${group})`);
    g.handlerCount_ += 1;
    return '';
  },

  ros_serve_action(block, g) {
    const full = fullType(typeOf(block), 'action');
    g.usesActionServer_ = true;
    const v = g.getVariableName(block.getFieldValue('VAR'));
    const name = g.callbackName('on_goal');
    g.serving_ = full;
    const body = g.statementToCode(block, 'DO');
    const result = g.message(full, g.valueToCode(block, 'RESULT', Order.NONE) || '{}', 'result');
    g.serving_ = null;
    const m = g.method(name, ['goal_handle'], `${I}${v} = goal_handle.request\n${body}${I}goal_handle.succeed()\n${I}return ${result}\n`);
    g.callbacks_.push(m);
    g.inits_.push(`ActionServer(self, ${g.type(full)}, ${nameOf(g, block, 'ACTION')}, self.${name}\${group})`);
    g.handlerCount_ += 1;
    return '';
  },

  ros_action_feedback(block, g) {
    if (!inServeAction(block) || !g.serving_) return 'raise RuntimeError(\'"send feedback" works inside "serve action" only\')\n';
    const value = g.valueToCode(block, 'VALUE', Order.NONE) || '{}';
    return `goal_handle.publish_feedback(${g.message(g.serving_, value, 'feedback')})\n`;
  },

  ros_cancel(block, g) {
    g.helpers_.add('cancel');
    return 'self.cancel_goals()\n';
  },

  ros_field(block, g) {
    const obj = g.valueToCode(block, 'OBJ', Order.MEMBER) || 'None';
    return [`${obj}${pathCode(block.getFieldValue('FIELD'))}`, Order.MEMBER];
  },

  ros_sleep(block, g) {
    g.helpers_.add('sleep');
    return `await self.sleep(${g.valueToCode(block, 'SECONDS', Order.NONE) || '0'})\n`;
  },

  ros_log(block, g) {
    const v = unwrap(g.valueToCode(block, 'VALUE', Order.NONE) || "''");
    return `self.get_logger().info(${STRING.test(v) ? v : `str(${v})`})\n`;
  },

  ros_stop(block, g) {
    g.helpers_.add('stop_robot');
    return 'self.stop_robot()\n';
  },

  ros_elapsed(block, g) {
    g.helpers_.add('elapsed');
    return ['self.elapsed()', Order.FUNCTION_CALL];
  },

  // a count loop over whole numbers as a teacher writes it: for self.i in range(1, self.n + 1)
  controls_for(block, g) {
    const v = g.getVariableName(block.getFieldValue('VAR'));
    const from = g.valueToCode(block, 'FROM', Order.NONE) || '0';
    const to = g.valueToCode(block, 'TO', Order.ADDITIVE) || '0';
    const by = g.valueToCode(block, 'BY', Order.NONE) || '1';
    const whole = (c) => /^-?\d+$/.test(c);
    if (!whole(from) || !whole(by) || Number(by) === 0) return pyGen.forBlock.controls_for.call(block, block, g);
    const step = Number(by);
    const stop = whole(to) ? String(Number(to) + Math.sign(step)) : `${to} ${step > 0 ? '+' : '-'} 1`;
    return `for ${v} in range(${from}, ${stop}${step === 1 ? '' : `, ${step}`}):\n${g.statementToCode(block, 'DO') || g.PASS}`;
  },

  // a procedure: a method (async: its calls may wait); its parameters are its own names
  procedures_defreturn(block, g) {
    const name = g.getProcedureName(block.getFieldValue('NAME'));
    const models = block.getVarModels();
    g.locals_ = new Set(models.map((m) => m.getId()));
    const params = models.map((m) => g.getVariableName(m.getId()));
    let body = block.getInput('STACK') ? g.statementToCode(block, 'STACK') : '';
    const ret = block.getInput('RETURN') ? g.valueToCode(block, 'RETURN', Order.NONE) : '';
    g.locals_ = null;
    if (ret) body += `${I}return ${ret}\n`;
    g.methods_.push(g.method(name, params, body || g.PASS, { forceAsync: true }));
    return null;
  },

  procedures_callreturn(block, g) {
    const name = g.getProcedureName(block.getFieldValue('NAME'));
    const args = block.getVarModels().map((_, i) => g.valueToCode(block, `ARG${i}`, Order.NONE) || 'None');
    return [`(await self.${name}(${args.join(', ')}))`, Order.ATOMIC];
  },

  procedures_callnoreturn(block, g) {
    const [code] = NODE_BLOCKS.procedures_callreturn(block, g);
    return `${code.slice(1, -1)}\n`;
  },
};
NODE_BLOCKS.procedures_defnoreturn = NODE_BLOCKS.procedures_defreturn;

// ---- the robot sets' and made blocks' specs (spec.js) in the node's words -----------------------------
const nodeLang = {
  ...pyLang,
  obj: (entries) => new Struct(entries),
  arr: (items) => `[${items.map((i) => (i instanceof Struct ? gen.dictCode(i) : i)).join(', ')}]`,
  ns: (name) => {
    const lit = RosNodeGenerator.literal(name);
    if (lit !== null) return gen.quote_(lit.replace(/^\/+/, '') || '/');
    if (name.startsWith("'/' + ")) return name.slice(6);
    if (name.startsWith("'/")) return `'${name.slice(2)}`;
    return `(${name}).lstrip('/')`;
  },
  field: (obj, path) => `${obj}${pathCode(pyLang.parseLiteral(path) ?? '')}`,
  helper: (name, args) => {
    if (name === 'rangeAt') gen.helpers_.add('range_at');
    if (name === 'yaw') gen.helpers_.add('yaw');
    if (name === 'pick') gen.helpers_.add('pick');
    return `${{ rangeAt: 'range_at', yaw: 'yaw', pick: 'pick' }[name]}(${args.join(', ')})`;
  },
  call: (name, args) => nodeCall(name, args),
  stmt: (name, args) => `${nodeCall(name, args).replace(/^\((await [^]*)\)$/, '$1')}\n`,
};

function robotParts(spec) {
  const e = spec.entries ? Object.fromEntries(spec.entries) : spec;
  return e;
}

function nodeCall(name, args) {
  const g = gen;
  switch (name) {
    case 'publish': {
      const [topic, type, msg] = args;
      const full = fullType(pyLang.parseLiteral(type));
      return g.publishCode(g.publisher(topic, full), full, msg).trimEnd();
    }
    case 'drive': {
      g.helpers_.add('drive');
      const [topic, type, msg, seconds] = args;
      const full = fullType(pyLang.parseLiteral(type));
      return `await self.drive(${g.publisher(topic, full)}, ${g.message(full, msg)}, ${seconds})`;
    }
    case 'move':
    case 'turn': {
      g.helpers_.add(name);
      const [robot, amount, speed] = args;
      const r = robotParts(robot);
      const cmd = g.publisher(r.cmd, fullType(pyLang.parseLiteral(r.type)));
      const pose = g.newest(r.pose, fullType(pyLang.parseLiteral(r.pose_type)));
      return `await self.${name}(${cmd}, ${pose}, ${coerce(amount, 'float64')}, ${coerce(speed, 'float64')})`;
    }
    case 'callService': {
      g.helpers_.add('call');
      const [service, type, request] = args;
      const full = fullType(pyLang.parseLiteral(type), 'srv');
      return `(await self.call(${g.client('client', service, full)}, ${g.message(full, request, 'request')}))`;
    }
    case 'sendGoal': {
      g.helpers_.add('send_goal');
      g.inits_.push('self.goals = []  # the goals sent and not done (cancel_goals())');
      const [action, type, goal] = args;
      const full = fullType(pyLang.parseLiteral(type), 'action');
      return `(await self.send_goal(${g.client('action', action, full)}, ${g.message(full, goal, 'goal')}))`;
    }
    case 'latest': {
      const [topic, type, path] = args;
      const msg = g.latest(topic, pyLang.parseLiteral(type));
      return path === undefined ? msg : `${msg}${pathCode(pyLang.parseLiteral(path) ?? '')}`;
    }
    default:
      throw new Error(`no ROS 2 node counterpart for ${name}`);
  }
}

export const gen = new RosNodeGenerator();
