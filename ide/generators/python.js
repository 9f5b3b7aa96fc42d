// Python for the IDE's own blocks: a whole script that needs only roslibpy. The
// runtime (runtime/rosgate_runtime.py) is copied into the file, so it runs anywhere:
//   pip install roslibpy && python3 program.py --url ws://HOST:9090/
/* global Blockly, python */
import { specToCode } from './spec.js';
import { inServeAction, isLoose, NameScope, NAME_KINDS } from './scope.js';

const { Order } = python;

const SNAKE = {
  publish: 'publish', drive: 'drive', move: 'move', turn: 'turn', latest: 'latest',
  callService: 'call_service', sendGoal: 'send_goal', rangeAt: 'range_at', yaw: 'yaw', pick: 'pick',
};

export const lang = {
  order: { NONE: Order.NONE, CALL: Order.FUNCTION_CALL, MUL: Order.MULTIPLICATIVE },
  none: 'None',
  num: (n) => String(n),
  bool: (b) => (b ? 'True' : 'False'),
  str: (s) => gen.quote_(s),
  arr: (items) => `[${items.join(', ')}]`,
  obj: (entries) => `{${entries.map(([k, c]) => `${gen.quote_(k)}: ${c}`).join(', ')}}`,
  concat: (parts) => parts.map((p) => (p.lit !== undefined && typeof p.lit === 'string' ? p.code : `str(${p.code})`)).join(' + '),
  neg: (c) => `-(${c})`,
  mul: (a, b) => `(${a}) * (${b})`,
  deg2rad: (c) => `math.radians(${c})`,
  degrees: (c) => `math.degrees(${c})`,
  call: (name, args) => `rt.${SNAKE[name]}(${args.join(', ')})`,
  stmt: (name, args) => `rt.${SNAKE[name]}(${args.join(', ')})\n`,
  helper: (name, args) => `${SNAKE[name]}(${args.join(', ')})`,
  field: (obj, path) => `field(${obj}, ${path})`,
  ns: (name) => `rt.ns(${name})`,
  parseLiteral(code) {
    if (/^-?\d+(\.\d+)?$/.test(code)) return Number(code);
    const m = /^'((?:[^'\\]|\\.)*)'$/.exec(code);
    if (m && !m[1].includes('\\')) return m[1];
    return undefined;
  },
};

let runtimeSource = '# the rosgate runtime was not loaded\n';
export function setRuntimeSource(text) { runtimeSource = text; }

export class RosPythonGenerator extends python.PythonGenerator {
  constructor() {
    super('Python');
    Object.assign(this.forBlock, python.pythonGenerator.forBlock);
    this.addReservedWords('rt,run,main,field,fmt,pick,yaw,range_at,angle_diff,pose_of,roslibpy,Runtime,' +
      'StopProgram,RosError,argparse,json,math,os,random,signal,sys,threading,time,traceback,message,queue,GAIN,SETTLE_SERVICE,is_velocity_type,zero_velocity,' +
      'norm_namespace,with_namespace,re,goal_handle');
    this.programName = 'program';
    this.namespace = '';      // the robot namespace the file runs in unless --ns says otherwise
    this.importRuntime = false;   // true: the text program imports the runtime (js/editors/textmode.js)
    this.scope = new NameScope();
  }

  init(workspace) {
    super.init(workspace);
    this.handlers_ = [];
    const map = workspace.getVariableMap();
    this.globals_ = map.getAllVariables().map((v) => this.getVariableName(v.getId()));
  }

  globalLine() {
    return this.globals_.length ? `${this.INDENT}global ${this.globals_.join(', ')}\n` : '';
  }

  // A function in the file's definitions; returns its name.
  defineCallback(block, prefix, varName, body) {
    const name = this.nameDB_.getDistinctName(prefix, Blockly.Names.NameType.PROCEDURE);
    this.definitions_[`%${name}`] =
      `def ${name}(message):\n${this.globalLine()}${this.INDENT}${varName} = message\n${body || this.PASS}`;
    return name;
  }

  finish(code) {
    const imports = [];
    const defs = [];
    for (const def of Object.values(this.definitions_)) {
      if (/^(from\s+\S+\s+)?import\s+\S+/.test(def)) imports.push(def); else defs.push(def);
    }
    const handlers = this.handlers_.map((h) => this.INDENT + h + '\n').join('');
    const body = this.prefixLines(code, this.INDENT);
    Blockly.CodeGenerator.prototype.finish.call(this, code);
    this.isInitialized = false;
    this.nameDB_.reset();
    const own = this.importRuntime ? imports : imports.filter((i) => !/^import (math|random|time|json|sys|os)$/.test(i.trim()));
    const doc = this.importRuntime ? `"""${this.programName.replace(/"""/g, "'''")}: a rosgate program in Python, made from its blocks.\n\n` +
      '▶ Run runs it in the rosgate IDE. Downloaded (the .py button bundles the runtime on its\n' +
      'import line), it needs only roslibpy:\n' +
      '    python3 this_file.py --url ws://localhost:9090/ [--ns /s07]\n"""\n'
      : `"""${this.programName.replace(/"""/g, "'''")}: a rosgate block program.\n\n` +
      'Needs only roslibpy (pip install roslibpy). Run it against any rosbridge server:\n' +
      '    python3 this_file.py --url ws://localhost:9090/ [--ns /s07]\n' +
      '(or set ROSBRIDGE_URL and ROSGATE_NS). --ns puts the robot blocks\' topics, services\n' +
      'and actions in that robot namespace. Ctrl-C stops the program and the robot.\n"""\n';
    const parts = [
      this.importRuntime ? 'from rosgate_runtime import *' : runtimeSource.trimEnd(),
      own.join('\n'),
      defs.join('\n\n').trim(),
      `def main():\n${this.globalLine()}${handlers}${body.trim() ? body : this.PASS}`.trimEnd(),
      `if __name__ == '__main__':\n    run(main${this.namespace ? `, namespace=${this.quote_(this.namespace)}` : ''})`,
    ].filter(Boolean);
    return `${doc}${parts.join('\n\n\n')}\n`;
  }

  msgArg(block, name) { return this.valueToCode(block, name, Order.NONE) || '{}'; }
  // A generic ROS block's topic, service or action name: in the robot namespace or as it is.
  nameArg(block, nameField) {
    const name = block.getFieldValue(nameField) ?? '';
    const quoted = this.quote_(name);
    return this.scope.inNamespace(NAME_KINDS[nameField], name) ? `rt.ns(${quoted})` : quoted;
  }

  topicArgs(block, nameField) {
    return `${this.nameArg(block, nameField)}, ${this.quote_(block.getFieldValue('TYPE') || '')}`;
  }

  // A loose value block (see scope.js) is not part of the program: no code.
  blockToCode(block, thisOnly) {
    if (block && isLoose(block)) return '';
    return super.blockToCode(block, thisOnly);
  }
}

export const gen = new RosPythonGenerator();
const F = gen.forBlock;

F.ros_publish = (block, g) => `rt.publish(${g.topicArgs(block, 'TOPIC')}, ${g.msgArg(block, 'MSG')})\n`;

F.ros_message = (block, g) => {
  const parts = [];
  for (const f of block.msgFields) {
    const code = g.valueToCode(block, `F_${f.name}`, Order.NONE);
    if (code) parts.push(`${g.quote_(f.name)}: ${code}`);
  }
  return [`{${parts.join(', ')}}`, Order.ATOMIC];
};

F.ros_on_message = (block, g) => {
  const v = g.getVariableName(block.getFieldValue('VAR'));
  const name = g.defineCallback(block, 'on_message', v, g.statementToCode(block, 'DO'));
  g.handlers_.push(`rt.on_message(${g.topicArgs(block, 'TOPIC')}, ${name})`);
  return '';
};

F.ros_latest = (block, g) =>
  [`rt.latest(${g.topicArgs(block, 'TOPIC')}, ${g.quote_(block.getFieldValue('FIELD') || '')})`, Order.FUNCTION_CALL];

F.ros_wait_message = (block, g) => `rt.wait_for_message(${g.topicArgs(block, 'TOPIC')})\n`;

F.ros_next_message = (block, g) => {
  const timeout = g.valueToCode(block, 'TIMEOUT', Order.NONE) || '0';
  return [`rt.wait_for_message(${g.topicArgs(block, 'TOPIC')}, ${timeout})`, Order.FUNCTION_CALL];
};

F.ros_call_service = (block, g) =>
  [`rt.call_service(${g.topicArgs(block, 'SERVICE')}, ${g.msgArg(block, 'REQUEST')})`, Order.FUNCTION_CALL];

F.ros_call_service_stmt = (block, g) =>
  `rt.call_service(${g.topicArgs(block, 'SERVICE')}, ${g.msgArg(block, 'REQUEST')})\n`;

F.ros_send_goal = (block, g) => {
  const fbVar = g.getVariableName(block.getFieldValue('FEEDBACK_VAR'));
  const resVar = g.getVariableName(block.getFieldValue('RESULT_VAR'));
  const fbBody = g.statementToCode(block, 'FEEDBACK');
  const onFeedback = fbBody ? g.defineCallback(block, 'on_feedback', fbVar, fbBody) : 'None';
  return `${resVar} = rt.send_goal(${g.topicArgs(block, 'ACTION')}, ${g.msgArg(block, 'GOAL')}, ${onFeedback})\n` +
    g.statementToCode(block, 'RESULT').replace(new RegExp(`^${g.INDENT}`, 'gm'), '');
};

// Server blocks: a function per block, served from the start of main().
function serveBlock(block, g, { method, prefix, nameField, answerInput, params }) {
  const v = g.getVariableName(block.getFieldValue('VAR'));
  const body = g.statementToCode(block, 'DO');
  const answer = g.valueToCode(block, answerInput, Order.NONE) || '{}';
  const name = g.nameDB_.getDistinctName(prefix, Blockly.Names.NameType.PROCEDURE);
  g.definitions_[`%${name}`] =
    `def ${name}(${params}):\n${g.globalLine()}${g.INDENT}${v} = message\n${body}${g.INDENT}return ${answer}`;
  g.handlers_.push(`rt.${method}(${g.topicArgs(block, nameField)}, ${name})`);
  return '';
}
F.ros_every = (block, g) => {
  const name = g.nameDB_.getDistinctName('every_tick', Blockly.Names.NameType.PROCEDURE);
  g.definitions_[`%${name}`] = `def ${name}():\n${g.globalLine()}${g.statementToCode(block, 'DO') || g.PASS}`;
  g.handlers_.push(`rt.every(${g.valueToCode(block, 'SECONDS', Order.NONE) || '1'}, ${name})`);
  return '';
};
F.ros_serve_service = (block, g) =>
  serveBlock(block, g, { method: 'serve_service', prefix: 'on_call', nameField: 'SERVICE', answerInput: 'RESPONSE', params: 'message' });
F.ros_serve_action = (block, g) =>
  serveBlock(block, g, { method: 'serve_action', prefix: 'on_goal', nameField: 'ACTION', answerInput: 'RESULT', params: 'message, goal_handle' });
F.ros_action_feedback = (block, g) =>
  `rt.action_feedback(${inServeAction(block) ? 'goal_handle' : 'None'}, ${g.valueToCode(block, 'VALUE', Order.NONE) || '{}'})\n`;

F.ros_cancel = (block, g) => `rt.cancel(${g.nameArg(block, 'ACTION')})\n`;

F.ros_field = (block, g) =>
  [`field(${g.valueToCode(block, 'OBJ', Order.NONE) || 'None'}, ${g.quote_(block.getFieldValue('FIELD'))})`, Order.FUNCTION_CALL];

F.ros_sleep = (block, g) => `rt.sleep(${g.valueToCode(block, 'SECONDS', Order.NONE) || '0'})\n`;
F.ros_log = (block, g) => `rt.log(${g.valueToCode(block, 'VALUE', Order.NONE) || "''"})\n`;
F.ros_stop = () => 'rt.stop_robot()\n';
F.ros_elapsed = () => ['rt.elapsed()', Order.FUNCTION_CALL];

export function registerSpec(type, spec) {
  F[type] = (block, g) => specToCode(g, block, spec, lang);
  F[type].spec = spec;      // the ROS 2 node's generator writes the same spec in its words (node.js)
}
