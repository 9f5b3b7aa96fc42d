// What the text editor offers from the live robot: inside the string where the runtime (or
// roslib / roslibpy) expects a topic, service or action, the graph's names with their types; in the
// string after it, the types; the runtime's functions with their arguments after `rt.`; the
// fields of a message whose type the call names. A name the graph lacks is underlined (a
// warning), never refused: the robot may not be up yet.
import { normType } from '../robot/graph.js';
import { withNamespace } from '../../runtime/util.js';
import { t } from '../i18n.js';

const KINDS = new Set(['topic', 'service', 'action']);   // the names the graph has, by kind

// The runtime's functions (runtime/runtime.js, runtime/rosgate_runtime.py) and their arguments.
const RT = {
  javascript: [
    ['publish', '(topic, type, msg)', 'publish one message'],
    ['drive', '(topic, type, msg, seconds)', 'publish msg at 10 Hz for seconds, then zero'],
    ['onMessage', '(topic, type, async (message) => {…})', 'run a function for every message'],
    ['waitForMessage', '(topic, type, timeout = 0)', 'wait for the next message'],
    ['latest', "(topic, type, field = '')", 'the newest message (or one field of it)'],
    ['callService', '(service, type, args = {}, timeout = 0)', 'call a service, wait for its answer'],
    ['sendGoal', '(action, type, goal = {}, onFeedback = null)', 'send an action goal, wait for its result'],
    ['cancel', '(action)', 'cancel the action goals sent'],
    ['sleep', '(seconds)', 'wait (await it)'],
    ['log', '(value)', 'print to the console'],
    ['move', '(spec, distance, speed = 1)', 'drive straight, closed loop on the pose'],
    ['turn', '(spec, degrees, speed = 90)', 'turn on the spot, closed loop on the pose'],
    ['stopRobot', '()', 'zero every velocity topic the program drove'],
    ['elapsed', '()', 'seconds since the program started'],
    ['field', '(obj, path)', "a field of a message by its path ('pose.x')"],
    ['pick', '(msg, selector, index = 0)', 'an element of an array field'],
    ['yaw', '(q)', 'the heading of a quaternion (radians)'],
    ['rangeAt', '(scan, degrees = 0, window = 20)', 'the nearest range of a LaserScan around an angle'],
    ['ns', '(name)', 'a name in the robot namespace'],
    ['every', '(seconds, async () => {…})', 'run a function every so many seconds'],
    ['serveService', '(service, type, async (request) => answer)', 'serve a service: answer every call'],
    ['serveAction', '(action, type, async (goal, goalHandle) => result)', 'serve an action: run every goal'],
    ['actionFeedback', '(goalHandle, values)', "send a served goal's feedback"],
  ],
  python: [
    ['publish', '(topic, t, msg)', 'publish one message'],
    ['drive', '(topic, t, msg, seconds)', 'publish msg at 10 Hz for seconds, then zero'],
    ['on_message', '(topic, t, handler)', 'call handler(message) for every message'],
    ['wait_for_message', '(topic, t, timeout=0)', 'wait for the next message'],
    ['latest', "(topic, t, path='')", 'the newest message (or one field of it)'],
    ['call_service', '(service, t, args=None, timeout=0)', 'call a service, wait for its answer'],
    ['send_goal', '(action, t, goal=None, on_feedback=None)', 'send an action goal, wait for its result'],
    ['cancel', '(action=None)', 'cancel the action goals sent'],
    ['sleep', '(seconds)', 'wait'],
    ['log', '(value)', 'print to the console'],
    ['move', '(spec, distance, speed=1.0)', 'drive straight, closed loop on the pose'],
    ['turn', '(spec, degrees, speed=90.0)', 'turn on the spot, closed loop on the pose'],
    ['stop_robot', '()', 'zero every velocity topic the program drove'],
    ['elapsed', '()', 'seconds since the program started'],
    ['ns', '(name)', 'a name in the robot namespace'],
    ['every', '(seconds, handler)', 'call handler() every so many seconds'],
    ['serve_service', '(service, t, handler)', 'serve a service: handler(request) returns the answer'],
    ['serve_action', '(action, t, handler)', 'serve an action: handler(goal, goal_handle) returns the result'],
    ['action_feedback', '(goal_handle, values)', "send a served goal's feedback"],
  ],
};
// The Python runtime's functions outside rt (from rosgate_runtime import *).
const PY_FUNCS = [
  ['field', '(obj, path)', "a field of a message by its path ('pose.x')"],
  ['pick', '(msg, selector, index=0)', 'an element of an array field'],
  ['yaw', '(q)', 'the heading of a quaternion (radians)'],
  ['range_at', '(scan, degrees=0, window=20)', 'the nearest range of a LaserScan around an angle'],
  ['angle_diff', '(a, b)', 'a - b wrapped to ±π'],
  ['run', '(main, namespace="")', 'connect, run main(), stop the robot at the end'],
];

// Which name a call's first string is, and what its message argument is.
const CALLS = {
  publish: ['topic', 'msg'], drive: ['topic', 'msg'], onMessage: ['topic'], on_message: ['topic'],
  waitForMessage: ['topic'], wait_for_message: ['topic'], latest: ['topic'],
  callService: ['service', 'request'], call_service: ['service', 'request'],
  sendGoal: ['action', 'goal'], send_goal: ['action', 'goal'], cancel: ['action'],
  // roslibpy: Topic(ros, '/name', 'type'), Service(...), ActionClient(...)
  Topic: ['topic'], Service: ['service'], ActionClient: ['action'], Action: ['action'],
};
const CALL_NAMES = Object.keys(CALLS).join('|');
// the string being typed as a call's first argument (rt.ns('…') too, roslibpy's after `ros, `)
const NAME_AT = new RegExp(`\\b(${CALL_NAMES})\\s*\\(\\s*(?:rt\\.ns\\(\\s*|\\w+\\s*,\\s*)?(['"])([^'"\\n]*)$`);
// roslib: new ROSLIB.Topic({ ros, name: '…' })
const ROSLIB_NAME_AT = /\b(Topic|Service|Action)\s*\(\s*\{[^}]*\bname\s*:\s*(['"])([^'"\n]*)$/;
// the second string: the type
const TYPE_AT = new RegExp(`\\b(${CALL_NAMES})\\s*\\(\\s*(?:rt\\.ns\\(\\s*)?(['"])([^'"\\n]*)\\2\\s*\\)?\\s*,\\s*(['"])([^'"\\n]*)$`);
// a call with its name and type, then the message being written
const MSG_AT = new RegExp(`\\b(${CALL_NAMES})\\s*\\(\\s*(?:rt\\.ns\\(\\s*)?(['"])([^'"\\n]*)\\2\\s*\\)?\\s*,\\s*(['"])([^'"\\n]*)\\4\\s*,\\s*(\\{[^()]*)$`);
const ROSLIB_TYPE = /\b(messageType|serviceType|actionType)\s*:\s*(['"])([^'"\n]*)$/;

function names(env, kind) {
  const graph = env.graph();
  if (!graph) return [];
  return graph.names(kind, env.ns()).map((name) => ({
    label: name, type: kind === 'topic' ? 'variable' : kind === 'service' ? 'function' : 'class',
    detail: graph.typeOf(kind, withNamespace(env.ns(), name)) || graph.typeOf(kind, name),
  }));
}

function types(env, kind, name) {
  const graph = env.graph();
  if (!graph) return [];
  const known = graph.typeOf(kind, withNamespace(env.ns(), name)) || graph.typeOf(kind, name);
  const all = kind === 'service' ? graph.serviceTypes() : kind === 'action' ? graph.actionTypes() : graph.messageTypes();
  const list = known ? [known, ...all.filter((t) => t !== known)] : all;
  return list.map((t, i) => ({ label: t, type: 'type', boost: t === known ? 10 : -i / 1000, detail: t === known ? `of ${name}` : '' }));
}

// The keys open around the cursor in a message literal: '{linear: {' -> ['linear'].
function openKeys(text) {
  const stack = [];
  let key = null;
  const re = /(['"]?)(\w+)\1\s*:|[{}]/g;
  let m;
  while ((m = re.exec(text))) {
    if (m[0] === '{') stack.push(key);
    else if (m[0] === '}') stack.pop();
    else key = m[2];
  }
  return stack.slice(1);   // the outer brace is the message itself
}

async function fields(env, kind, type, path) {
  const graph = env.graph();
  if (!graph?.connected || !type) return [];
  let defs;
  try { defs = await graph.details(kind, type); } catch { return []; }
  if (!defs?.length) return [];
  const byType = new Map(defs.map((d) => [normType(d.type), d]));
  let def = defs[0];
  for (const key of path) {
    const i = def.fieldnames.indexOf(key);
    def = i < 0 ? null : byType.get(normType(def.fieldtypes[i]));
    if (!def) return [];
  }
  return def.fieldnames.map((name, i) => ({ label: name, type: 'property', detail: def.fieldtypes[i] }));
}

export function completionSource(lang, env) {
  return async (ctx) => {
    const line = ctx.state.doc.lineAt(ctx.pos);
    const before = ctx.state.sliceDoc(Math.max(0, ctx.pos - 400), ctx.pos);
    const inLine = ctx.state.sliceDoc(line.from, ctx.pos);
    let m = NAME_AT.exec(inLine);
    if (m) return { from: ctx.pos - m[3].length, options: names(env, CALLS[m[1]][0]), validFor: /^[\w/~]*$/ };
    m = ROSLIB_NAME_AT.exec(before);
    if (m) return { from: ctx.pos - m[3].length, options: names(env, m[1] === 'Topic' ? 'topic' : m[1].toLowerCase()), validFor: /^[\w/~]*$/ };
    m = TYPE_AT.exec(inLine);
    if (m) return { from: ctx.pos - m[5].length, options: types(env, CALLS[m[1]][0], m[3]), validFor: /^[\w/]*$/ };
    m = ROSLIB_TYPE.exec(inLine);
    if (m) return { from: ctx.pos - m[3].length, options: types(env, m[1].replace('Type', '').replace('message', 'topic'), ''), validFor: /^[\w/]*$/ };
    m = MSG_AT.exec(before);
    if (m && CALLS[m[1]][1]) {
      const word = ctx.matchBefore(/\w*/);
      const quoted = /['"]\w*$/.test(inLine);
      if (!quoted && !/[{,]\s*\w*$/.test(before)) return null;
      const options = await fields(env, CALLS[m[1]][1], m[5], openKeys(m[6]));
      return options.length ? { from: word.from, options, validFor: /^\w*$/ } : null;
    }
    const member = ctx.matchBefore(/\brt\.\w*$/);
    if (member) {
      return {
        from: member.from + 3,
        options: RT[lang()].map(([label, args, info]) => ({ label, type: 'method', detail: args, info })),
        validFor: /^\w*$/,
      };
    }
    if (lang() === 'python') {
      const word = ctx.matchBefore(/\w+/);
      if (!word || (ctx.state.sliceDoc(word.from - 1, word.from) === '.')) return null;
      return { from: word.from, options: PY_FUNCS.map(([label, args, info]) => ({ label, type: 'function', detail: args, info })), validFor: /^\w*$/ };
    }
    return null;
  };
}

// Names in name strings that the graph does not have (once the graph is read).
const NAME_USE = new RegExp(`\\b(${CALL_NAMES})\\s*\\(\\s*(rt\\.ns\\(\\s*)?(?:\\w+\\s*,\\s*)?(['"])(\\/[^'"\\s]*)\\3`, 'g');
const ROSLIB_USE = /\b(Topic|Service|Action)\s*\(\s*\{[^}]*?\bname\s*:\s*(['"])(\/[^'"\s]*)\2/g;

export function unknownNames(text, env) {
  const graph = env.graph();
  if (!graph?.loaded) return [];
  const ns = env.ns();
  const out = [];
  const check = (kind, name, at, inNs) => {
    const known = (k) => graph.has(k, name) || (ns && graph.has(k, withNamespace(ns, name)));
    if (kind ? known(kind) : ['topic', 'service', 'action'].some(known)) return;
    out.push({ from: at, to: at + name.length, name, kind: kind || 'name', inNs });
  };
  for (const m of text.matchAll(NAME_USE)) {
    check(CALLS[m[1]][0], m[4], m.index + m[0].length - m[4].length - 1, Boolean(m[2]));
  }
  for (const m of text.matchAll(ROSLIB_USE)) {
    check(m[1] === 'Topic' ? 'topic' : m[1].toLowerCase(), m[3], m.index + m[0].length - m[3].length - 1);
  }
  return out;
}

export function lintSource(lang, env) {
  return (view) => unknownNames(view.state.doc.toString(), env).map((u) => ({
    from: u.from, to: u.to, severity: 'warning', source: 'robot',
    message: t(`completion.unknown.${KINDS.has(u.kind) ? u.kind : 'name'}`, { name: u.name }),
  }));
}
