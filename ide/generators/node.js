// A ROS 2 node (rclpy) for the IDE's own blocks: the same Python the script generator writes for
// each block (they share forBlock), put in a Node class whose __init__ makes the publishers,
// subscriptions and clients the blocks name, and whose program() is the main stack. The runtime
// (runtime/rosgate_node.py) runs program() in its own thread while a MultiThreadedExecutor spins.
/* global Blockly */
import { gen as pyGen, RosPythonGenerator } from './python.js';

// A name as the blocks write it: rt.ns('/x') (relative in the node: the node's namespace) or '/x'.
const NAME = String.raw`(?:rt\.ns\('([^'\\]*)'\)|'([^'\\]*)')`;
const TYPE = String.raw`'([A-Za-z]\w*/(?:msg|srv|action)/\w+|[A-Za-z]\w*/\w+)'`;
const USES = [
  ['publisher', new RegExp(String.raw`rt\.(?:publish|drive)\(${NAME}, ${TYPE}`, 'g')],
  ['subscription', new RegExp(String.raw`rt\.(?:on_message|latest|wait_for_message)\(${NAME}, ${TYPE}`, 'g')],
  ['service_client', new RegExp(String.raw`rt\.call_service\(${NAME}, ${TYPE}`, 'g')],
  ['action_client', new RegExp(String.raw`rt\.send_goal\(${NAME}, ${TYPE}`, 'g')],
];
const ROBOT = new RegExp(String.raw`\{'cmd': ${NAME}, 'type': ${TYPE}, 'pose': ${NAME}, 'pose_type': ${TYPE}\}`, 'g');
const ANY_TYPE = /'([A-Za-z]\w*)\/(msg|srv|action)\/(\w+)'/g;

const relative = (ns, plain) => (ns !== undefined ? ns.replace(/^\/+/, '') || '/' : plain);

// What a program's code uses: [{kind, name, type}] (names known when the code is written; others
// are made on first use) and the ROS packages of every type it names.
export function rosUses(code) {
  const uses = new Map();
  const add = (kind, name, type) => { if (!uses.has(`${kind} ${name}`)) uses.set(`${kind} ${name}`, { kind, name, type }); };
  for (const [kind, re] of USES) {
    for (const m of code.matchAll(re)) add(kind, relative(m[1], m[2]), m[3]);
  }
  for (const m of code.matchAll(ROBOT)) {
    add('publisher', relative(m[1], m[2]), m[3]);
    add('subscription', relative(m[4], m[5]), m[6]);
  }
  const packages = new Set(['rclpy']);
  for (const m of code.matchAll(ANY_TYPE)) packages.add(m[1]);
  return { uses: [...uses.values()], packages: [...packages].sort() };
}

const full = (t) => (t.split('/').length === 2 ? t.replace('/', '/msg/') : t);
const camel = (s) => s.split('_').map((w) => w.charAt(0).toUpperCase() + w.slice(1)).join('');

// A Python class name for each type, from PKG.KIND import NAME (as PkgName where two share a name).
function typeImports(types) {
  const byName = new Map();
  for (const t of types) {
    const name = t.split('/')[2];
    byName.set(name, [...(byName.get(name) ?? []), t]);
  }
  const alias = new Map();
  const lines = [];
  for (const t of [...new Set(types)].sort()) {
    const [pkg, kind, name] = t.split('/');
    const as = byName.get(name).length > 1 ? camel(pkg) + name : name;
    alias.set(t, as);
    lines.push(`from ${pkg}.${kind} import ${name}${as === name ? '' : ` as ${as}`}`);
  }
  return { alias, lines: [...new Set(lines)] };
}

export const safeIdent = (s, fallback) => (String(s).toLowerCase().replace(/\W+/g, '_').replace(/^_+|_+$/g, '').replace(/^(\d)/, '_$1') || fallback);

class RosNodeGenerator extends RosPythonGenerator {
  constructor() {
    super();
    this.forBlock = pyGen.forBlock;     // one definition per block, robot sets and made blocks too
    this.INDENT = '    ';
    this.addReservedWords('self,BlockNode,run_node,interface,to_message,to_dict,main,program');
    this.packageName = 'rosgate_program';
    this.nodeName = 'program';
  }

  finish(code) {
    const imports = [];
    const defs = [];
    for (const def of Object.values(this.definitions_)) {
      if (/^(from\s+\S+\s+)?import\s+\S+/.test(def)) imports.push(def); else defs.push(def);
    }
    const I = this.INDENT;
    const handlers = this.handlers_.map((h) => I + I + h + '\n').join('');
    const body = this.prefixLines(code, I + I);
    Blockly.CodeGenerator.prototype.finish.call(this, code);
    this.isInitialized = false;
    this.nameDB_.reset();
    const program = `${defs.join('\n')}\n${handlers}${body}`;
    const { uses } = rosUses(program);
    const { alias, lines } = typeImports(uses.map((u) => full(u.type)));
    const cls = camel(this.nodeName) || 'Program';
    const init = uses.map((u) => `${I}${I}self.${u.kind}(${this.quote_(u.name)}, ${alias.get(full(u.type))})\n`).join('');
    const globals = this.globals_.length ? `${I}${I}global ${this.globals_.join(', ')}\n` : '';
    const pkg = this.packageName;
    const doc = `"""${this.programName.replace(/"""/g, "'''")}: a rosgate block program as a ROS 2 node (rclpy).\n\n` +
      `In a colcon workspace (this package in src/):\n    colcon build && source install/setup.bash\n` +
      `    ros2 run ${pkg} ${this.nodeName}${this.namespace ? '' : ' [--ros-args -r __ns:=/s07]'}\n` +
      'The program runs in a thread of its own while a MultiThreadedExecutor spins the node, so no\n' +
      'callback waits for a sleep block (see rosgate_node.py). Ctrl-C stops it and the robot.\n"""\n';
    if (/\bmath\./.test(program) && !imports.some((i) => /^import math$/m.test(i))) imports.unshift('import math');
    const parts = [
      [...imports, ...lines, `from ${pkg}.rosgate_node import *  # BlockNode, run_node and the blocks' helpers (field, yaw ...)`].join('\n'),
      'rt = None  # the running node (run_node sets it): the blocks\' functions call rt.*',
      defs.join('\n\n').trim(),
      `class ${cls}(BlockNode):\n${I}def __init__(self):\n` +
        `${I}${I}super().__init__(${this.quote_(this.nodeName)}, namespace=${this.quote_(this.namespace || '')})\n${init}\n` +
        `${I}def program(self):\n${globals}${handlers}${body.trim() ? body : I + I + 'pass\n'}`.trimEnd(),
      `def main(args=None):\n${I}raise SystemExit(run_node(${cls}, args))`,
      `if __name__ == '__main__':\n${I}main()`,
    ].filter(Boolean);
    return `${doc}${parts.join('\n\n\n')}\n`;
  }
}

export const gen = new RosNodeGenerator();
