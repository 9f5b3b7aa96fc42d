// JavaScript for the IDE's own blocks. The code is the body of an async function of
// `rt` (runtime/runtime.js); instrumented code also calls rt.step(blockId) before
// every statement, for highlighting, Pause/Step and Stop.
/* global Blockly, javascript */
import { specToCode } from './spec.js';
import { inServeAction, isLoose, NameScope, NAME_KINDS } from './scope.js';

const { Order } = javascript;

export const lang = {
  order: { NONE: Order.NONE, CALL: Order.FUNCTION_CALL, MUL: Order.MULTIPLICATION },
  none: 'null',
  num: (n) => (n < 0 ? `(${n})` : String(n)),
  bool: (b) => (b ? 'true' : 'false'),
  str: (s) => gen.quote_(s),
  arr: (items) => `[${items.join(', ')}]`,
  obj: (entries) => `{${entries.map(([k, c]) => `${/^[A-Za-z_$][\w$]*$/.test(k) ? k : gen.quote_(k)}: ${c}`).join(', ')}}`,
  concat: (parts) => parts.map((p) => p.code).join(' + '),
  neg: (c) => `-(${c})`,
  mul: (a, b) => `(${a}) * (${b})`,
  deg2rad: (c) => `(${c}) * Math.PI / 180`,
  degrees: (c) => `${c} * 180 / Math.PI`,
  call: (name, args, isAsync) => (isAsync ? `(await rt.${name}(${args.join(', ')}))` : `rt.${name}(${args.join(', ')})`),
  stmt: (name, args, isAsync) => `${isAsync ? 'await ' : ''}rt.${name}(${args.join(', ')});\n`,
  helper: (name, args) => `rt.${name}(${args.join(', ')})`,
  field: (obj, path) => `rt.field(${obj}, ${path})`,
  ns: (name) => `rt.ns(${name})`,
  parseLiteral(code) {
    if (/^-?\d+(\.\d+)?$/.test(code)) return Number(code);
    if (/^\(-\d+(\.\d+)?\)$/.test(code)) return Number(code.slice(1, -1));
    const m = /^'((?:[^'\\]|\\.)*)'$/.exec(code);
    if (m && !m[1].includes('\\')) return m[1];
    return undefined;
  },
};

class RosJavascriptGenerator extends javascript.JavascriptGenerator {
  constructor() {
    super('JavaScript');
    Object.assign(this.forBlock, javascript.javascriptGenerator.forBlock);
    this.addReservedWords('rt,await,async,goalHandle');
    this.scope = new NameScope();   // the page shares one with the Python generator
  }

  // Generated code for a workspace; `instrument` adds rt.step()/rt.tick() calls.
  generate(workspace, { instrument = false } = {}) {
    this.STATEMENT_PREFIX = instrument ? 'await rt.step(%1);\n' : null;
    this.INFINITE_LOOP_TRAP = instrument ? 'await rt.tick();\n' : null;
    try {
      return this.workspaceToCode(workspace);
    } finally {
      this.STATEMENT_PREFIX = null;
      this.INFINITE_LOOP_TRAP = null;
    }
  }

  msgArg(block, name) { return this.valueToCode(block, name, Order.COMMA) || '{}'; }
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

export const gen = new RosJavascriptGenerator();
const F = gen.forBlock;

// Functions become async so that their bodies may wait.
for (const t of ['procedures_defreturn', 'procedures_defnoreturn']) {
  const base = F[t];
  F[t] = function (block, g) {
    base.call(this, block, g);
    const key = '%' + g.getProcedureName(block.getFieldValue('NAME'));
    g.definitions_[key] = g.definitions_[key].replace(/(^|\n)function /, '$1async function ');
    return null;
  };
}
{
  const ret = F.procedures_callreturn;
  F.procedures_callreturn = (block, g) => [`(await ${ret(block, g)[0]})`, Order.ATOMIC];
  const noret = F.procedures_callnoreturn;
  F.procedures_callnoreturn = (block, g) => `await ${noret(block, g)}`;
}

F.ros_publish = (block, g) => `rt.publish(${g.topicArgs(block, 'TOPIC')}, ${g.msgArg(block, 'MSG')});\n`;

F.ros_message = (block, g) => {
  const parts = [];
  for (const f of block.msgFields) {
    const code = g.valueToCode(block, `F_${f.name}`, Order.COMMA);
    if (code) parts.push(`${f.name}: ${code}`);
  }
  return [`{${parts.join(', ')}}`, Order.ATOMIC];
};

F.ros_on_message = (block, g) => {
  block.suppressPrefixSuffix = true;
  const v = g.getVariableName(block.getFieldValue('VAR'));
  const body = g.statementToCode(block, 'DO');
  g.definitions_[`%on_message_${block.id}`] =
    `rt.onMessage(${g.topicArgs(block, 'TOPIC')}, async (message) => {\n${g.INDENT}${v} = message;\n${body}});`;
  return '';
};

F.ros_latest = (block, g) =>
  [`(await rt.latest(${g.topicArgs(block, 'TOPIC')}, ${g.quote_(block.getFieldValue('FIELD') || '')}))`, Order.ATOMIC];

F.ros_wait_message = (block, g) => `await rt.waitForMessage(${g.topicArgs(block, 'TOPIC')});\n`;

F.ros_next_message = (block, g) => {
  const timeout = g.valueToCode(block, 'TIMEOUT', Order.COMMA) || '0';
  return [`(await rt.waitForMessage(${g.topicArgs(block, 'TOPIC')}, ${timeout}))`, Order.ATOMIC];
};

F.ros_call_service = (block, g) =>
  [`(await rt.callService(${g.topicArgs(block, 'SERVICE')}, ${g.msgArg(block, 'REQUEST')}))`, Order.ATOMIC];

F.ros_call_service_stmt = (block, g) =>
  `await rt.callService(${g.topicArgs(block, 'SERVICE')}, ${g.msgArg(block, 'REQUEST')});\n`;

F.ros_send_goal = (block, g) => {
  const fbVar = g.getVariableName(block.getFieldValue('FEEDBACK_VAR'));
  const resVar = g.getVariableName(block.getFieldValue('RESULT_VAR'));
  const fbBody = g.statementToCode(block, 'FEEDBACK');
  const onFeedback = fbBody ? `async (message) => {\n${g.INDENT}${fbVar} = message;\n${fbBody}}` : 'null';
  return `${resVar} = await rt.sendGoal(${g.topicArgs(block, 'ACTION')}, ${g.msgArg(block, 'GOAL')}, ${onFeedback});\n` +
    g.statementToCode(block, 'RESULT').replace(new RegExp(`^${g.INDENT}`, 'gm'), '');
};

// Server blocks: registered before the main blocks run, as message handlers are.
function serveBlock(block, g, { method, nameField, answerInput, params }) {
  block.suppressPrefixSuffix = true;
  const v = g.getVariableName(block.getFieldValue('VAR'));
  const body = g.statementToCode(block, 'DO');
  const answer = g.valueToCode(block, answerInput, Order.NONE) || '{}';
  g.definitions_[`%${method}_${block.id}`] =
    `rt.${method}(${g.topicArgs(block, nameField)}, async (${params}) => {\n${g.INDENT}${v} = message;\n${body}${g.INDENT}return ${answer};\n});`;
  return '';
}
F.ros_every = (block, g) => {
  block.suppressPrefixSuffix = true;
  g.definitions_[`%every_${block.id}`] =
    `rt.every(${g.valueToCode(block, 'SECONDS', Order.COMMA) || '1'}, async () => {\n${g.statementToCode(block, 'DO')}});`;
  return '';
};
F.ros_serve_service = (block, g) => serveBlock(block, g, { method: 'serveService', nameField: 'SERVICE', answerInput: 'RESPONSE', params: 'message' });
F.ros_serve_action = (block, g) => serveBlock(block, g, { method: 'serveAction', nameField: 'ACTION', answerInput: 'RESULT', params: 'message, goalHandle' });
F.ros_action_feedback = (block, g) =>
  `rt.actionFeedback(${inServeAction(block) ? 'goalHandle' : 'null'}, ${g.valueToCode(block, 'VALUE', Order.COMMA) || '{}'});\n`;

F.ros_cancel = (block, g) => `rt.cancel(${g.nameArg(block, 'ACTION')});\n`;

F.ros_field = (block, g) =>
  [`rt.field(${g.valueToCode(block, 'OBJ', Order.COMMA) || 'null'}, ${g.quote_(block.getFieldValue('FIELD'))})`, Order.FUNCTION_CALL];

F.ros_sleep = (block, g) => `await rt.sleep(${g.valueToCode(block, 'SECONDS', Order.NONE) || '0'});\n`;
F.ros_log = (block, g) => `rt.log(${g.valueToCode(block, 'VALUE', Order.NONE) || "''"});\n`;
F.ros_stop = () => 'rt.stopRobot();\n';
F.ros_elapsed = () => ['rt.elapsed()', Order.FUNCTION_CALL];

// Blocks defined by data (robot sets, "make a block").
export function registerSpec(type, spec) {
  F[type] = (block, g) => specToCode(g, block, spec, lang);
}
