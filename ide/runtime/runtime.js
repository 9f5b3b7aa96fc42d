// The API that generated JavaScript calls. Every call that talks to ROS returns a
// Promise that rejects on a rosbridge `status` error or a failed result. stop()
// ends the program: pending waits reject, subscriptions end, goals are cancelled
// and every velocity topic the program drove gets a zero command.
import { fmt, field, pick, yaw, rangeAt, zeroVelocity, isVelocityType, poseOf, angleDiff,
  normNamespace, withNamespace } from './util.js';

export { fmt, field, pick, yaw, rangeAt };

export class StopSignal extends Error {
  constructor() { super('program stopped'); this.name = 'StopSignal'; }
}

export class RosError extends Error {
  constructor(msg) { super(msg); this.name = 'RosError'; }
}

let runCounter = 0;
const PAGE_TAG = Math.random().toString(36).slice(2, 8);   // ids of this page's runs, not another tab's
const GAIN = 6;   // proportional gain of move/turn near the goal (1/s)
// A closed loop stops on the pose it last saw, and its last command runs on for the round trip
// (most of a second on a loaded machine: 0.2 m or 10 degrees). Once the robot has come to rest
// the loop looks again and takes it back, up to PASSES times, until it is within REST_REACH m or
// REST_HEADING rad of its goal.
const PASSES = 3;
const REST_REACH = 0.02;
const REST_HEADING = 0.01;
const SETTLE_SERVICE = '/rosapi/get_time';   // the round trip at the end of a run (settle)

export class Runtime {
  /**
   * @param ros a connected roslib Ros
   * @param hooks {log(text), highlight(blockId), error(err, blockId), held(blockId): paused before or in a block}
   * @param options {namespace}: the robot namespace robot blocks' names go in (rt.ns)
   */
  constructor(ros, hooks = {}, { namespace = '' } = {}) {
    this.ros = ros;
    this.hooks = hooks;
    this.namespace = normNamespace(namespace);
    this.run = ++runCounter;
    this.tag = `rosgate${PAGE_TAG}.${this.run}`;
    this.n = 0;
    this.stopped = false;
    this.paused = false;
    this.stepping = false;        // paused by Step: blocks run whole, each part holds before its next
    this.current = null;          // id of the block running now
    this.started = performance.now();
    this.pending = new Set();     // {reject} of every promise stop() must end
    this.subs = new Map();        // topic -> {id, type, latest, waiters:Set, handlers:[]}
    this.advertised = new Map();  // topic -> type
    this.velocityTopics = new Map();
    this.goals = new Map();       // goal id -> action
    this.servers = [];            // {event, listener, unadvertise}: the services and actions it serves
    this.timers = [];             // setInterval ids of its 'every N s' blocks
    this.owned = new Map();       // op|name|block -> {id, unwatch}: ids of ops no promise waits on
    this.lastYield = performance.now();
    this._gates = new Set();      // resolvers of the parts (main, handlers) held while paused
    // A status error with no id that names a topic this run advertised ends it too.
    this._onStatus = (m) => {
      const topic = /^publish: ([^:\s]+):/.exec(m.msg ?? '')?.[1];
      if (m.level === 'error' && this.advertised.has(topic)) this._fail(new RosError(m.msg));
    };
    ros.on('status', this._onStatus);
  }

  // The id of an op nothing waits a reply for (publish, advertise), one per op, name and block:
  // a status error about it ends the program on that block. Ops a promise waits on (calls,
  // goals, subscriptions) reject that promise instead.
  _owned(op, name, blockId = this.current) {
    const key = `${op}|${name}|${blockId}`;
    let entry = this.owned.get(key);
    if (!entry) {
      const id = this._id(op, name);
      entry = { id, unwatch: this._watchStatus(id, (m) => this._fail(new RosError(statusText(m)), blockId)) };
      this.owned.set(key, entry);
    }
    return entry.id;
  }

  // A robot block's name in the robot namespace.
  ns(name) { return withNamespace(this.namespace, name); }

  _id(op, name) { return `${op}:${name}:${this.tag}.${++this.n}`; }

  _send(msg) { this.ros.callOnConnection(msg); }

  // A promise that stop() rejects.
  _track(executor) {
    let entry;
    const p = new Promise((resolve, reject) => {
      entry = { reject };
      this.pending.add(entry);
      executor((v) => { this.pending.delete(entry); resolve(v); },
        (e) => { this.pending.delete(entry); reject(e); }, entry);
    });
    if (this.stopped) { this.pending.delete(entry); return Promise.reject(new StopSignal()); }
    return p;
  }

  _watchStatus(id, onError) {
    const ev = `status:${id}`;
    const cb = (m) => { if (m.level === 'error') onError(m); };
    this.ros.on(ev, cb);
    return () => this.ros.off(ev, cb);
  }

  // ---- program control -------------------------------------------------
  // Before every block: a paused program holds here (the block before it has ended).
  async step(blockId) {
    if (this.stopped) throw new StopSignal();
    this.current = blockId;
    this.hooks.highlight?.(blockId);
    await this._hold(false);
    await this.tick();
  }

  // While paused: the robot stands still and the program waits for Resume or Step. Inside a
  // block (drive, move, turn: `inside`) only Pause holds: a block Step let go runs to its end.
  async _hold(inside = true) {
    if (!this.paused || (inside && this.stepping)) return;
    this.stopRobot();
    const blockId = this.current;
    await this._track((resolve) => {
      this._gates.add(resolve);
      this.hooks.held?.(blockId);
    });
  }

  // Loop trap: lets the page breathe inside tight loops.
  async tick() {
    if (this.stopped) throw new StopSignal();
    const now = performance.now();
    if (now - this.lastYield > 30) {
      this.lastYield = now;
      await new Promise((r) => setTimeout(r, 0));
      if (this.stopped) throw new StopSignal();
    }
  }

  pause() { this.paused = true; this.stepping = false; }
  resume() { this.paused = false; this.stepping = false; this._release(); }
  // Every held part (the main program, a message handler) runs its next block, then holds.
  stepOnce() { this.paused = true; this.stepping = true; this._release(); }
  _release() { const gates = [...this._gates]; this._gates.clear(); for (const g of gates) g(); }

  elapsed() { return (performance.now() - this.started) / 1000; }

  sleep(seconds) {
    const ms = Math.max(0, Number(seconds) || 0) * 1000;
    return this._track((resolve) => { setTimeout(resolve, ms); });
  }

  log(value) { this.hooks.log?.(fmt(value)); }

  // ---- topics ----------------------------------------------------------
  advertise(topic, type) {
    if (this.advertised.get(topic) === type) return;
    const id = this._owned('advertise', topic);
    this._send({ op: 'advertise', id, topic, type });
    this.advertised.set(topic, type);
  }

  publish(topic, type, msg) {
    if (this.stopped) throw new StopSignal();
    this.advertise(topic, type);
    if (isVelocityType(type)) this.velocityTopics.set(topic, type);
    this._send({ op: 'publish', id: this._owned('publish', topic), topic, msg });
  }

  _subscribe(topic, type) {
    let sub = this.subs.get(topic);
    if (sub) return sub;
    const id = this._id('subscribe', topic);
    const blockId = this.current;
    sub = { id, type, latest: undefined, waiters: new Set(), handlers: [] };
    sub.listener = (m) => this._deliver(sub, m.msg);
    sub.unwatch = this._watchStatus(id, (m) => {
      const err = new RosError(statusText(m));
      for (const w of sub.waiters) w.reject(err);
      sub.waiters.clear();
      this._fail(err, blockId);
    });
    this.ros.on(topic, sub.listener);
    this.subs.set(topic, sub);
    this._send({ op: 'subscribe', id, topic, type });
    return sub;
  }

  _deliver(sub, msg) {
    if (this.stopped) return;
    sub.latest = msg;
    for (const w of sub.waiters) w.resolve(msg);
    sub.waiters.clear();
    for (const h of sub.handlers) h(msg);
  }

  _next(sub, timeout) {
    return this._track((resolve, reject) => {
      let timer = null;
      const w = {
        resolve: (m) => { clearTimeout(timer); resolve(m); },
        reject: (e) => { clearTimeout(timer); reject(e); },
      };
      sub.waiters.add(w);
      if (timeout > 0) {
        timer = setTimeout(() => {
          sub.waiters.delete(w);
          reject(new RosError(`no message on ${this._topicOf(sub)} within ${timeout} s`));
        }, timeout * 1000);
      }
    });
  }

  _topicOf(sub) { for (const [t, s] of this.subs) if (s === sub) return t; return '?'; }

  // Runs handler(msg) for every message; a handler still busy keeps only the newest message.
  onMessage(topic, type, handler) {
    const sub = this._subscribe(topic, type);
    let busy = false;
    let queued;
    let hasQueued = false;
    const blockId = this.current;
    const run = async (msg) => {
      busy = true;
      try {
        await handler(msg);
      } catch (e) {
        if (!(e instanceof StopSignal)) this._fail(e, this.current ?? blockId);
        return;
      } finally { busy = false; }
      if (hasQueued && !this.stopped) { hasQueued = false; run(queued); }
    };
    sub.handlers.push((msg) => {
      if (busy) { queued = msg; hasQueued = true; } else run(msg);
    });
  }

  async waitForMessage(topic, type, timeout = 0) {
    return this._next(this._subscribe(topic, type), Number(timeout) || 0);
  }

  async latest(topic, type, path = '') {
    const sub = this._subscribe(topic, type);
    const msg = sub.latest !== undefined ? sub.latest : await this._next(sub, 10);
    return path ? field(msg, path) : msg;
  }

  // ---- services and actions ------------------------------------------
  callService(service, type, args = {}, timeout = 0) {
    const id = this._id('call_service', service);
    return this._track((resolve, reject) => {
      const done = () => { this.ros.off(id, onReply); unwatch(); };
      const onReply = (m) => {
        if (m.op !== 'service_response') return;
        done();
        if (m.result === false) {
          reject(new RosError(`service ${service} failed: ${typeof m.values === 'string' ? m.values : JSON.stringify(m.values)}`));
        } else resolve(m.values ?? {});
      };
      const unwatch = this._watchStatus(id, (m) => {
        done();
        reject(new RosError(`call_service ${service}: ${statusText(m)}`));
      });
      this.ros.on(id, onReply);
      const op = { op: 'call_service', id, service, args: args ?? {} };
      if (type) op.type = type;
      if (timeout > 0) op.timeout = Number(timeout);
      this._send(op);
    });
  }

  sendGoal(action, type, goal = {}, onFeedback = null) {
    const id = this._id('send_action_goal', action);
    const blockId = this.current;
    let chain = Promise.resolve();   // feedback handlers run one after another, in order
    return this._track((resolve, reject) => {
      const done = () => { this.ros.off(id, onReply); unwatch(); this.goals.delete(id); };
      const onReply = (m) => {
        if (m.op === 'action_feedback') {
          if (!onFeedback) return;
          chain = chain.then(() => (this.stopped ? null : onFeedback(m.values))).catch((e) => {
            if (!(e instanceof StopSignal)) this._fail(e, this.current ?? blockId);
          });
        } else if (m.op === 'action_result') {
          done();
          if (m.result === false || (m.status !== undefined && m.status !== 4)) {
            const what = { 5: 'was canceled', 6: 'was aborted' }[m.status] ?? `ended with status ${m.status}`;
            const detail = typeof m.values === 'string' ? `: ${m.values}` : '';
            reject(new RosError(`action ${action} ${what}${detail}`));
          } else chain.then(() => resolve(m.values ?? {}));
        }
      };
      const unwatch = this._watchStatus(id, (m) => {
        done();
        reject(new RosError(`send_action_goal ${action}: ${statusText(m)}`));
      });
      this.ros.on(id, onReply);
      this.goals.set(id, action);
      this._send({ op: 'send_action_goal', id, action, action_type: type, args: goal ?? {}, feedback: true });
    });
  }

  // "every N s": handler() every `seconds`; a tick that comes while it still runs is skipped.
  every(seconds, handler) {
    const blockId = this.current;
    let busy = false;
    const timer = setInterval(async () => {
      if (busy || this.stopped) return;
      busy = true;
      try {
        await handler();
      } catch (e) {
        clearInterval(timer);
        if (!(e instanceof StopSignal)) this._fail(e, this.current ?? blockId);
      } finally { busy = false; }
    }, Math.max(0.01, Number(seconds) || 0) * 1000);
    this.timers.push(timer);
  }

  // ---- servers: services and actions the program serves through the gateway ---------
  // handler(request) answers each call; several calls may run at once, each in its own turn.
  serveService(service, type, handler) {
    this._serve('advertise_service', { service, type }, service, 'call_service', async (m, blockId) => {
      const [values, ok] = await this._served(handler, [m.args ?? {}], blockId);
      this._send({ op: 'service_response', service, id: m.id, values: ok ? values ?? {} : 'the program failed', result: ok });
    }, { op: 'unadvertise_service', service });
  }

  // handler(goal, goalHandle) runs each goal; actionFeedback(goalHandle, values) sends its feedback.
  serveAction(action, type, handler) {
    this._serve('advertise_action', { action, type }, action, 'send_action_goal', async (m, blockId) => {
      const [values, ok] = await this._served(handler, [m.args ?? {}, { action, id: m.id }], blockId);
      this._send({ op: 'action_result', action, id: m.id, values: ok ? values ?? {} : {}, status: ok ? 4 : 6, result: ok });
    }, { op: 'unadvertise_action', action });
  }

  actionFeedback(goalHandle, values) {
    if (!goalHandle) throw new RosError("'send feedback' works inside 'serve action' only");
    if (this.stopped) throw new StopSignal();
    this._send({ op: 'action_feedback', action: goalHandle.action, id: goalHandle.id, values: values ?? {} });
  }

  _serve(op, fields, event, requestOp, answer, unadvertise) {
    const blockId = this.current;
    const listener = (m) => { if (m.op === requestOp && !this.stopped) answer(m, blockId); };
    this.ros.on(event, listener);
    this.servers.push({ event, listener, unadvertise });
    this._send({ op, id: this._owned(op, event, blockId), ...fields });
  }

  // [handler's answer, true], or [undefined, false] when it failed (the program ends) or stopped.
  async _served(handler, args, blockId) {
    try {
      return [await handler(...args), true];
    } catch (e) {
      if (!(e instanceof StopSignal)) this._fail(e, this.current ?? blockId);
      return [undefined, false];
    }
  }

  // Message handlers, timers or servers keep the program running after its main blocks.
  listening() {
    return this.servers.length > 0 || this.timers.length > 0 || [...this.subs.values()].some((s) => s.handlers.length);
  }

  cancel(action) {
    for (const [id, a] of this.goals) {
      if (!action || a === action) this._send({ op: 'cancel_action_goal', id, action: a });
    }
  }

  // ---- the end ---------------------------------------------------------
  // Waits until the gateway has answered every op this run sent, before the run may say
  // "finished": a publish has no reply, so a status error about the program's last publish
  // could arrive after the end and be lost. The gateway answers ops in order, so the reply to
  // one more call (a cheap rosapi one; its own result does not matter) comes after any status
  // about the ops before it. Bounded by `timeout` s: a server without rosapi may never answer.
  settle(timeout = 2) {
    if (!this.owned.size) return Promise.resolve();
    const id = this._id('call_service', SETTLE_SERVICE);
    return this._track((resolve) => {
      const done = () => {
        clearTimeout(timer);
        this.ros.off(id, done);
        this.ros.off(`status:${id}`, done);
        resolve();
      };
      const timer = setTimeout(done, timeout * 1000);
      this.ros.on(id, done);
      this.ros.on(`status:${id}`, done);
      this._send({ op: 'call_service', id, service: SETTLE_SERVICE, args: {} });
    });
  }

  // ---- robot helpers ---------------------------------------------------
  stopRobot() {
    for (const [topic, type] of this.velocityTopics) {
      this._send({ op: 'publish', topic, msg: zeroVelocity(type) });
    }
  }

  // Publishes msg at 10 Hz for `seconds`, then zero.
  async drive(topic, type, msg, seconds) {
    const end = performance.now() + Math.max(0, Number(seconds) || 0) * 1000;
    try {
      while (performance.now() < end) {
        await this._hold();
        this.publish(topic, type, msg);
        await this.sleep(Math.min(0.1, (end - performance.now()) / 1000));
      }
    } finally {
      if (!this.stopped) this.publish(topic, type, zeroVelocity(type));
    }
  }

  // The pose once the robot has come to rest after a loop's zero: two poses in a row alike, within
  // a second (a robot whose odometry never rests: its newest; one that publishes no more: its last).
  async _rested(spec) {
    const sub = this._subscribe(spec.pose, spec.pose_type);
    const pose = async () => {
      try { return poseOf(await this._next(sub, 2), spec.pose_type); } catch (e) {
        if (this.stopped) throw e;
        return poseOf(sub.latest, spec.pose_type);
      }
    };
    const end = performance.now() + 1000;
    let prev = await pose();
    while (performance.now() < end) {
      const p = await pose();
      if (Math.abs(p.x - prev.x) < 1e-3 && Math.abs(p.y - prev.y) < 1e-3 && Math.abs(angleDiff(p.theta, prev.theta)) < 1e-3) return p;
      prev = p;
    }
    return prev;
  }

  // Drives straight for `distance` (negative: backwards), closed loop on the pose topic.
  async move(spec, distance, speed = 1) {
    distance = Number(distance) || 0;
    const start = poseOf(await this.latest(spec.pose, spec.pose_type), spec.pose_type);
    const sign = Math.sign(distance);
    const goal = Math.abs(distance);
    const type = spec.type ?? 'geometry_msgs/msg/Twist';
    const left = (p) => goal - Math.hypot(p.x - start.x, p.y - start.y);
    try {
      for (let pass = 0; pass < PASSES; pass++) {
        let dir = 0;   // a pass drives one way, to the goal or past it (no hunting on a late pose)
        for (;;) {
          await this._hold();
          const remaining = left(poseOf(await this.latest(spec.pose, spec.pose_type), spec.pose_type));
          dir ||= Math.sign(remaining);
          if (dir * remaining <= 0.01) break;
          const v = Math.max(0.1, Math.min(Number(speed), GAIN * Math.abs(remaining)));
          this.publish(spec.cmd, type, twist(type, sign * dir * v, 0));
          await this.sleep(0.02);
        }
        this.publish(spec.cmd, type, zeroVelocity(type));
        if (Math.abs(left(await this._rested(spec))) <= REST_REACH) break;
      }
    } finally {
      if (!this.stopped) this.publish(spec.cmd, type, zeroVelocity(type));
    }
  }

  // Turns by `degrees` (positive: left), closed loop on the pose topic.
  async turn(spec, degrees, speed = 90) {
    const target = (Number(degrees) || 0) * Math.PI / 180;
    const rate = Number(speed) * Math.PI / 180;
    const type = spec.type ?? 'geometry_msgs/msg/Twist';
    let last = poseOf(await this.latest(spec.pose, spec.pose_type), spec.pose_type).theta;
    let turned = 0;
    const seen = (th) => { turned += angleDiff(th, last); last = th; return target - turned; };
    try {
      for (let pass = 0; pass < PASSES; pass++) {
        let dir = 0;
        for (;;) {
          await this._hold();
          const remaining = seen(poseOf(await this.latest(spec.pose, spec.pose_type), spec.pose_type).theta);
          dir ||= Math.sign(remaining);
          if (dir * remaining <= 0.005) break;
          const w = Math.max(0.1, Math.min(rate, GAIN * Math.abs(remaining)));
          this.publish(spec.cmd, type, twist(type, 0, dir * w));
          await this.sleep(0.02);
        }
        this.publish(spec.cmd, type, zeroVelocity(type));
        if (Math.abs(seen((await this._rested(spec)).theta)) <= REST_HEADING) break;
      }
    } finally {
      if (!this.stopped) this.publish(spec.cmd, type, zeroVelocity(type));
    }
  }

  field(obj, path) { return field(obj, path); }
  pick(msg, selector, index) { return pick(msg, selector, index); }
  yaw(q) { return yaw(q); }
  rangeAt(scan, degrees, window) { return rangeAt(scan, degrees, window); }

  // ---- errors and the end --------------------------------------------
  _fail(err, blockId = this.current) {
    if (this.stopped) return;
    const e = err instanceof Error ? err : new RosError(String(err));
    this.hooks.error?.(e, blockId);
  }

  // Ends the program; safe to call more than once and from pagehide.
  stop() {
    if (this.stopped) return;
    this.stopped = true;
    this.stopRobot();
    this.ros.off('status', this._onStatus);
    for (const { unwatch } of this.owned.values()) unwatch();
    this.owned.clear();
    this.cancel();
    for (const [topic, sub] of this.subs) {
      this.ros.off(topic, sub.listener);
      sub.unwatch();
      this._send({ op: 'unsubscribe', id: sub.id, topic });
    }
    this.subs.clear();
    for (const topic of this.advertised.keys()) this._send({ op: 'unadvertise', topic });
    this.advertised.clear();
    for (const { event, listener, unadvertise } of this.servers) {
      this.ros.off(event, listener);
      this._send(unadvertise);
    }
    this.servers = [];
    for (const timer of this.timers) clearInterval(timer);
    this.timers = [];
    const signal = new StopSignal();
    for (const p of this.pending) p.reject(signal);
    this.pending.clear();
    this._release();
  }
}

// A status message without the op id the runtime made up (the block already says where).
function statusText(m) {
  return String(m.msg ?? '').replace(` (id ${m.id})`, '');
}

function twist(type, linear, angular) {
  const t = { linear: { x: linear, y: 0, z: 0 }, angular: { x: 0, y: 0, z: angular } };
  return /TwistStamped$/.test(type) ? { header: { frame_id: '' }, twist: t } : t;
}
