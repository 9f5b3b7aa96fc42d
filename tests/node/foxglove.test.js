// The Foxglove WebSocket protocol on rosgate's port, with what Foxglove and Lichtblick use: npm
// @foxglove/ws-protocol 0.8.0's FoxgloveClient over `ws`, the schemas parsed by @foxglove/rosmsg
// and the CDR read and written by @foxglove/rosmsg2-serialization.
//
// Without ROSGATE_URL, sim gateways are started here (turtlesim; one with --auth). With it
// (tests/backends/test_foxglove_graph.py: rclpy gateways on a Jazzy graph), the gateway there is
// used, and ROSGATE_AUTH_URL, ROSGATE_TOKENS, ROSGATE_POSE_TYPE, ROSGATE_ADD_TYPE and
// ROSGATE_PARAM name that graph's gateway with --auth, its tokens, the turtle's pose type, the
// adder's type and a parameter to read and set.
import { after, before, describe, test } from 'node:test';
import assert from 'node:assert/strict';
import { randomBytes } from 'node:crypto';
import { once } from 'node:events';
import { mkdtempSync, writeFileSync } from 'node:fs';
import net from 'node:net';
import { tmpdir } from 'node:os';
import path from 'node:path';
import wsProtocol from '@foxglove/ws-protocol';
import rosmsg from '@foxglove/rosmsg';
import serialization from '@foxglove/rosmsg2-serialization';
import WebSocket from 'ws';
import { startGateway, withTimeout } from './support.js';

const { FoxgloveClient } = wsProtocol;   // CommonJS packages: their names come with the default export
const { parse } = rosmsg;
const { MessageReader, MessageWriter } = serialization;

const env = process.env;
const onGraph = Boolean(env.ROSGATE_URL);
const TOKENS = env.ROSGATE_TOKENS ? JSON.parse(env.ROSGATE_TOKENS)
  : { operator: 'fox-operator-7f3a', viewer: 'fox-viewer-2c9d' };
const POSE_TYPE = env.ROSGATE_POSE_TYPE || 'turtlesim/msg/Pose';
const ADD_TYPE = env.ROSGATE_ADD_TYPE || 'example_interfaces/srv/AddTwoInts';
const PARAM = env.ROSGATE_PARAM || '/turtlesim.background_r';
const TWIST = 'geometry_msgs/msg/Twist';
const WAIT = 15000;
const started = [];
let url;
let authUrl;

// A FoxgloveClient whose events are kept, and waited for with a deadline.
class Fox {
  constructor(address, headers = {}) {
    this.ws = new WebSocket(address, [FoxgloveClient.SUPPORTED_SUBPROTOCOL], { headers });
    this.client = new FoxgloveClient({ ws: this.ws });
    this.channels = new Map();   // topic -> channel
    this.services = new Map();   // name -> service
    this.statuses = [];
    this.messages = new Map();   // subscription id -> [{ timestamp, data }]
    this.params = [];
    this.graph = [];
    this.calls = new Map();      // call id -> response or failure
    this.closed = false;
    this.waiters = new Set();
    const c = this.client;
    c.on('serverInfo', (info) => { this.info = info; this.poke(); });
    c.on('status', (s) => { this.statuses.push(s); this.poke(); });
    c.on('advertise', (chans) => { for (const ch of chans) this.channels.set(ch.topic, ch); this.advertised = true; this.poke(); });
    c.on('unadvertise', (ids) => {
      for (const [topic, ch] of this.channels) if (ids.includes(ch.id)) this.channels.delete(topic);
      this.poke();
    });
    c.on('advertiseServices', (list) => { for (const s of list) this.services.set(s.name, s); this.poke(); });
    c.on('message', (m) => {
      const list = this.messages.get(m.subscriptionId) ?? [];
      list.push({ timestamp: m.timestamp, data: new Uint8Array(m.data.buffer, m.data.byteOffset, m.data.byteLength) });
      this.messages.set(m.subscriptionId, list);
      this.poke();
    });
    c.on('parameterValues', (p) => { this.params.push(p); this.poke(); });
    c.on('connectionGraphUpdate', (g) => { this.graph.push(g); this.poke(); });
    c.on('serviceCallResponse', (r) => { this.calls.set(r.callId, r); this.poke(); });
    c.on('serviceCallFailure', (f) => { this.calls.set(f.callId, f); this.poke(); });
    c.on('close', () => { this.closed = true; this.poke(); });
    c.on('error', () => {});
  }

  poke() {
    for (const w of [...this.waiters]) {
      const value = w.check();
      if (value) { this.waiters.delete(w); w.resolve(value); }
    }
  }

  until(check, what, ms = WAIT) {
    const value = check();
    if (value) return Promise.resolve(value);
    let waiter;
    const promise = new Promise((resolve) => { waiter = { check, resolve }; this.waiters.add(waiter); });
    return withTimeout(promise, ms, what).finally(() => this.waiters.delete(waiter));
  }

  channel(topic) { return this.until(() => this.channels.get(topic), `channel ${topic}`); }

  status(pattern, level = 2) {
    return this.until(() => this.statuses.find((s) => s.level === level && pattern.test(s.message)),
      `status ${pattern}; got ${JSON.stringify(this.statuses.map((s) => s.message))}`);
  }

  async subscribe(topic) {
    const channel = await this.channel(topic);
    const reader = new MessageReader(parse(channel.schema, { ros2: true }));
    const id = this.client.subscribe(channel.id);
    return { id, channel, read: (m) => reader.readMessage(m.data), all: () => this.messages.get(id) ?? [] };
  }

  // the n-th message (counting from 1) of a subscription, decoded
  async nth(sub, n, what) {
    await this.until(() => sub.all().length >= n, `${what}: ${n} messages`);
    return sub.read(sub.all()[n - 1]);
  }

  async writer(type) {
    const channel = [...this.channels.values()].find((ch) => ch.schemaName === type)
      ?? assert.fail(`no channel of ${type} to take its schema from`);
    return new MessageWriter(parse(channel.schema, { ros2: true }));
  }

  ready() { return this.until(() => this.advertised, 'the first advertise'); }

  close(name = 'client') { this.ws.close(); return this.until(() => this.closed, `${name} to close`); }
}

// A Foxglove client that reads nothing until asked: a websocket by hand on a TCP socket that is
// left paused (the `ws` package resumes its socket by itself, so it cannot play a slow reader).
class Stalled {
  static async open(address) {
    const target = new URL(address);
    const stalled = new Stalled(net.connect(Number(target.port), target.hostname));
    await once(stalled.socket, 'connect');
    stalled.socket.write(`GET ${target.pathname} HTTP/1.1\r\nHost: ${target.host}\r\nUpgrade: websocket\r\n`
      + `Connection: Upgrade\r\nSec-WebSocket-Key: ${randomBytes(16).toString('base64')}\r\n`
      + 'Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.websocket.v1\r\n\r\n');
    while (!stalled.buffer.includes('\r\n\r\n')) await stalled.more();
    stalled.socket.pause();
    const end = stalled.buffer.indexOf('\r\n\r\n') + 4;
    assert.match(stalled.buffer.subarray(0, end).toString(), /^HTTP\/1.1 101[^]*Sec-WebSocket-Protocol: foxglove.websocket.v1/i);
    stalled.buffer = stalled.buffer.subarray(end);
    return stalled;
  }

  constructor(socket) {
    this.socket = socket;
    this.buffer = Buffer.alloc(0);
    this.wake = null;
    socket.on('data', (chunk) => {   // one listener for the socket's life: no chunk is lost between reads
      this.buffer = Buffer.concat([this.buffer, chunk]);
      this.wake?.();
    });
  }

  more() { return new Promise((resolve) => { this.wake = resolve; }); }

  send(op) {   // one masked text frame (a client's must be masked)
    const payload = Buffer.from(JSON.stringify(op));
    const mask = randomBytes(4);
    const header = payload.length < 126 ? Buffer.from([0x81, 0x80 | payload.length])
      : Buffer.from([0x81, 0x80 | 126, payload.length >> 8, payload.length & 0xff]);
    this.socket.write(Buffer.concat([header, mask, payload.map((b, i) => b ^ mask[i % 4])]));
  }

  // reads frames ({opcode, text?}) until one passes `check`; returns them all
  async readUntil(check, what) {
    const frames = [];
    const read = async () => {
      this.socket.resume();
      for (;;) {
        const frame = this.#frame();
        if (frame) {
          frames.push(frame);
          if (check(frame)) return frames;
        } else {
          await this.more();
        }
      }
    };
    return withTimeout(read(), WAIT, what).catch((e) => {
      const texts = frames.filter((f) => f.text).map((f) => f.text.slice(0, 80));
      throw new Error(`${e.message} (read ${frames.length} frames, ${this.buffer.length} bytes pending; `
        + `texts ${JSON.stringify(texts)})`);
    });
  }

  #frame() {
    const b = this.buffer;
    if (b.length < 2) return null;
    let size = b[1] & 0x7f;
    let at = 2;
    if (size === 126) { if (b.length < 4) return null; size = b.readUInt16BE(2); at = 4; }
    else if (size === 127) { if (b.length < 10) return null; size = Number(b.readBigUInt64BE(2)); at = 10; }
    if (b.length < at + size) return null;
    const opcode = b[0] & 0x0f;
    const payload = b.subarray(at, at + size);
    this.buffer = b.subarray(at + size);
    return opcode === 1 ? { opcode, text: payload.toString() } : { opcode };
  }
}

const twist = (x, z = 0) => ({ linear: { x, y: 0, z: 0 }, angular: { x: 0, y: 0, z } });

before(async () => {
  if (onGraph) {
    url = env.ROSGATE_URL;
    authUrl = env.ROSGATE_AUTH_URL;
    return;
  }
  const dir = mkdtempSync(path.join(tmpdir(), 'rosgate-fox-'));
  const tokens = path.join(dir, 'tokens.toml');
  writeFileSync(tokens, Object.entries(TOKENS).map(([role, token]) =>
    `[[tokens]]\nname = "${role}-fox"\nrole = "${role}"\ntoken = "${token}"\n`).join('\n'));
  const open = await startGateway(['--robot', 'turtlesim', '--history', 'none', '--send-buffer-limit', '262144', '--cmd-timeout', '0',
    '--unregister-timeout', '0.5']);
  const locked = await startGateway(['--robot', 'turtlesim', '--history', 'none', '--auth', tokens, '--auth-timeout', '60']);
  started.push(open, locked);
  url = open.url;
  authUrl = locked.url;
});

after(async () => {
  for (const g of started) await g.stop();
});

// Drives with a client channel until the turtle has moved `far` along x (commands every 100 ms,
// as a joystick would), then sends a zero. Returns how far it went.
async function drive(fox, far = 0.4) {
  const pose = await fox.subscribe('/turtle1/pose');
  const x0 = (await fox.nth(pose, 1, 'pose')).x;
  const writer = await fox.writer(TWIST);
  const cmd = fox.client.advertise({ topic: '/turtle1/cmd_vel', encoding: 'cdr', schemaName: TWIST });
  let moved = 0;
  const timer = setInterval(() => fox.client.sendMessage(cmd, writer.writeMessage(twist(1.0))), 100);
  try {
    await fox.until(() => {
      const all = pose.all();
      moved = pose.read(all[all.length - 1]).x - x0;
      return Math.abs(moved) > far;
    }, 'the turtle to move');
  } finally {
    clearInterval(timer);
    fox.client.sendMessage(cmd, writer.writeMessage(twist(0)));
  }
  fox.client.unsubscribe(pose.id);
  return moved;
}

describe('the Foxglove protocol', () => {
  let fox;
  before(async () => { fox = new Fox(url); await fox.ready(); });
  after(async () => { await fox?.close(); });

  test('serverInfo names the capabilities and encodings; channels carry ros2msg schemas', async () => {
    assert.deepEqual(new Set(fox.info.capabilities),
      new Set(['clientPublish', 'parameters', 'parametersSubscribe', 'services', 'connectionGraph']));
    assert.deepEqual(fox.info.supportedEncodings, ['cdr', 'json']);
    assert.equal(fox.info.metadata.ROS_DISTRO, 'jazzy');
    const pose = await fox.channel('/turtle1/pose');
    assert.equal(pose.encoding, 'cdr');
    assert.equal(pose.schemaEncoding, 'ros2msg');
    assert.equal(pose.schemaName, POSE_TYPE);
    const cmd = await fox.channel('/turtle1/cmd_vel');
    assert.equal(cmd.schemaName, TWIST);
    const defs = parse(cmd.schema, { ros2: true });   // the whole text: Twist and Vector3
    assert.deepEqual(defs[0].definitions.map((f) => f.name), ['linear', 'angular']);
    assert.ok(defs.some((d) => /Vector3$/.test(d.name ?? '')), cmd.schema);
  });

  test('channels come and go with the graph', async () => {
    const other = new Fox(url);
    try {
      await other.ready();
      const mine = other.client.advertise({ topic: '/fox/passing', encoding: 'json', schemaName: 'std_msgs/msg/String' });
      const channel = await fox.channel('/fox/passing');
      assert.equal(channel.schemaName, 'std_msgs/msg/String');
      other.client.unadvertise(mine);   // its publisher goes after --unregister-timeout, and the topic with it
      await fox.until(() => !fox.channels.has('/fox/passing'), 'the channel unadvertised');
    } finally {
      await other.close();
    }
  });

  test('messages arrive as CDR with their receive time, and decode', async () => {
    const pose = await fox.subscribe('/turtle1/pose');
    const msg = await fox.nth(pose, 2, 'pose');
    for (const field of ['x', 'y', 'theta']) assert.equal(typeof msg[field], 'number', JSON.stringify(msg));
    const [first, second] = pose.all();
    assert.ok(first.timestamp > 1_600_000_000_000_000_000n && second.timestamp >= first.timestamp);
    fox.client.unsubscribe(pose.id);
  });

  test('a client publish moves the turtle', async () => {
    assert.ok(await drive(fox) > 0.4);
  });

  test('a client channel in JSON publishes too', async () => {
    const pose = await fox.subscribe('/turtle1/pose');
    const theta0 = (await fox.nth(pose, 1, 'pose')).theta;
    const cmd = fox.client.advertise({ topic: '/turtle1/cmd_vel', encoding: 'json', schemaName: 'geometry_msgs/Twist' });
    const timer = setInterval(() => fox.client.sendMessage(cmd, Buffer.from(JSON.stringify(twist(0, 1.5)))), 100);
    try {
      await fox.until(() => {
        const all = pose.all();
        return Math.abs(pose.read(all[all.length - 1]).theta - theta0) > 0.3;
      }, 'the turtle to turn');
    } finally {
      clearInterval(timer);
      fox.client.sendMessage(cmd, Buffer.from(JSON.stringify(twist(0))));
      fox.client.unadvertise(cmd);
      fox.client.unsubscribe(pose.id);
    }
  });

  test('services are advertised with their request and response schemas and called in CDR', async () => {
    const add = await fox.until(() => fox.services.get('/add_two_ints'), 'service /add_two_ints');
    assert.equal(add.type, ADD_TYPE);
    assert.equal(add.request.schemaName, `${ADD_TYPE}_Request`);
    assert.equal(add.request.encoding, 'cdr');
    const request = new MessageWriter(parse(add.request.schema, { ros2: true }));
    const response = new MessageReader(parse(add.response.schema, { ros2: true }));
    const basic = ADD_TYPE.endsWith('BasicTypes');   // test_msgs stands in where example_interfaces is missing
    const data = request.writeMessage(basic ? { int64_value: 19n, int32_value: 23 } : { a: 19n, b: 23n });
    fox.client.sendServiceCallRequest({ serviceId: add.id, callId: 1, encoding: 'cdr', data });
    const answer = await fox.until(() => fox.calls.get(1), 'the call\'s response');
    assert.equal(answer.op, 3, JSON.stringify(answer));   // a serviceCallResponse, not a failure
    const values = response.readMessage(answer.data);
    assert.equal(BigInt(basic ? values.int64_value : values.sum), 42n);
    fox.client.sendServiceCallRequest({ serviceId: add.id, callId: 2, encoding: 'cdr', data: new Uint8Array([1, 2]) });
    const bad = await fox.until(() => fox.calls.get(2), 'the bad call\'s failure');
    assert.equal(bad.op, 'serviceCallFailure');
    assert.match(bad.message, /\/add_two_ints: cannot deserialize/);
    fox.client.sendServiceCallRequest({ serviceId: 999999, callId: 3, encoding: 'cdr', data });
    assert.match((await fox.until(() => fox.calls.get(3), 'unknown service')).message, /not advertised/);
  });

  test('parameters: get, set (answered with the new value) and updates to a subscriber', async () => {
    fox.client.getParameters([PARAM], 'get-1');
    const got = await fox.until(() => fox.params.find((p) => p.id === 'get-1'), 'getParameters');
    assert.equal(got.parameters.length, 1, JSON.stringify(got));
    const old = got.parameters[0];
    const other = new Fox(url);
    try {
      await other.ready();
      other.client.subscribeParameterUpdates([PARAM]);
      // its ops are read in order: once a later one is answered, it follows the parameter (the set
      // below comes on another connection, which the gateway may read first)
      other.client.getParameters([PARAM], 'following');
      await other.until(() => other.params.find((p) => p.id === 'following'), 'getParameters after the subscribe');
      const fresh = old.type === 'float64' ? old.value + 0.5 : (old.value + 7) % 256;
      fox.client.setParameters([{ name: PARAM, value: fresh, type: old.type }], 'set-1');
      const set = await fox.until(() => fox.params.find((p) => p.id === 'set-1'), 'setParameters');
      assert.deepEqual(set.parameters.map((p) => p.value), [fresh]);
      await other.until(() => other.params.find((p) => p.parameters.some((q) => q.name === PARAM && q.value === fresh)),
        'the update to a subscriber');
      fox.client.setParameters([{ name: PARAM, value: old.value, type: old.type }], 'set-2');
      await fox.until(() => fox.params.find((p) => p.id === 'set-2'), 'setParameters back');
    } finally {
      await other.close();
    }
  });

  test('the connection graph names who publishes what', async () => {
    fox.client.subscribeConnectionGraph();
    const update = await fox.until(() => fox.graph.find((g) => g.publishedTopics.some((t) => t.name === '/turtle1/pose')),
      'a connection graph with /turtle1/pose');
    const pose = update.publishedTopics.find((t) => t.name === '/turtle1/pose');
    assert.ok(pose.publisherIds.includes('/turtlesim'), JSON.stringify(pose));
    assert.ok(update.advertisedServices.some((s) => s.name === '/add_two_ints'));
    fox.client.unsubscribeConnectionGraph();
  });

  test('a bad op gets a status naming op and field, and the connection carries on', async () => {
    fox.ws.send(JSON.stringify({ op: 'subscribe', subscriptions: [{ id: 'seven', channelId: 1 }] }));
    await fox.status(/^subscribe: field 'subscriptions\[0\]\.id' must be an integer/);
    fox.ws.send(Buffer.from([0x07, 1, 2]));
    await fox.status(/unknown binary opcode 0x07/);
    fox.client.sendMessage(4242, new Uint8Array([0, 1, 0, 0]));
    await fox.status(/^messageData: channel 4242 is not advertised by this client/);
    const pose = await fox.subscribe('/turtle1/pose');
    await fox.nth(pose, 1, 'pose after the bad ops');
    fox.client.unsubscribe(pose.id);
  });

  test('a slow client does not stall the others; it is told what it lost', async () => {
    const publisher = new Fox(url);
    const fast = new Fox(url);
    let slow;
    try {
      await publisher.ready();
      const bulk = publisher.client.advertise({ topic: '/fox/bulk', encoding: 'json', schemaName: 'std_msgs/msg/String' });
      publisher.client.sendMessage(bulk, Buffer.from(JSON.stringify({ data: 'first' })));
      const subFast = await fast.subscribe('/fox/bulk');
      slow = await Stalled.open(url);   // subscribes, then reads nothing: its kernel buffers fill, then its outbox
      slow.send({ op: 'subscribe', subscriptions: [{ id: 1, channelId: subFast.channel.id }] });
      const text = 'x'.repeat(64 * 1024);
      const count = 60;
      const big = () => subFast.all().filter((m) => subFast.read(m).data.length > 64 * 1024);
      for (let i = 0; i < count; i++) {   // each in turn, once the fast client has the one before
        publisher.client.sendMessage(bulk, Buffer.from(JSON.stringify({ data: `${i} ${text}` })));
        await fast.until(() => big().length === i + 1, `message ${i} to the fast client while the other reads nothing`);
      }
      assert.deepEqual(big().map((m) => Number(subFast.read(m).data.split(' ')[0])), [...Array(count).keys()]);
      const frames = await slow.readUntil((f) => f.text?.includes('not reading fast enough'), 'the slow client\'s warning');
      assert.match(frames.at(-1).text, /"level":1,"message":"client is not reading fast enough: dropped \d+ topic messages/);
      assert.ok(frames.filter((f) => f.opcode === 2).length < count);
    } finally {
      slow?.socket.destroy();
      await Promise.all([publisher.close('publisher'), fast.close('fast')]);
    }
  });

  test('a driving client that disconnects leaves the turtle stopped', async () => {
    const watcher = new Fox(url);
    const driver = new Fox(url);
    try {
      await driver.ready();
      const cmds = await watcher.subscribe('/turtle1/cmd_vel');
      const writer = await driver.writer(TWIST);
      const cmd = driver.client.advertise({ topic: '/turtle1/cmd_vel', encoding: 'cdr', schemaName: TWIST });
      const timer = setInterval(() => driver.client.sendMessage(cmd, writer.writeMessage(twist(0.8))), 100);
      try {   // a joystick held: commands until the watcher has seen three
        await watcher.until(() => cmds.all().filter((m) => cmds.read(m).linear.x === 0.8).length >= 3, 'moving commands');
      } finally {
        clearInterval(timer);
      }
      driver.ws.terminate();   // gone without a word, as a dropped link
      const zero = await watcher.until(() => {
        const all = cmds.all().map((m) => cmds.read(m));
        const moving = all.findIndex((m) => m.linear.x === 0.8);
        return all.slice(moving).find((m) => m.linear.x === 0 && m.angular.z === 0);
      }, 'the gateway\'s stop command');
      assert.ok(zero);
    } finally {
      await Promise.all([watcher.close(), driver.closed ? null : driver.close()]);
    }
  });
});

describe('the Foxglove protocol under --auth', () => {
  test('without a token: told so, shown nothing, and a publish is refused', async () => {
    const fox = new Fox(authUrl);
    try {
      await fox.status(/not authenticated: connect with \?token=/);
      await fox.ready();
      assert.equal(fox.channels.size, 0);
      assert.equal(fox.services.size, 0);
      const cmd = fox.client.advertise({ topic: '/turtle1/cmd_vel', encoding: 'cdr', schemaName: TWIST });
      await fox.status(/^advertise \(id \d+\): not authenticated/);
      fox.client.sendMessage(cmd, new Uint8Array([0, 1, 0, 0]));
      await fox.status(/^messageData: channel \d+ is not advertised/);
    } finally {
      await fox.close();
    }
  });

  test('a viewer\'s token shows the robot but may not drive it', async () => {
    const fox = new Fox(`${authUrl}?token=${encodeURIComponent(TOKENS.viewer)}`);
    try {
      await fox.channel('/turtle1/pose');
      fox.client.advertise({ topic: '/turtle1/cmd_vel', encoding: 'cdr', schemaName: TWIST });
      await fox.status(/role viewer may not publish to \/turtle1\/cmd_vel/);
      // a viewer calls only what reads: the nodes' parameter reads (rules/access.py PARAM_READS), the rates
      await fox.until(() => fox.services.size > 0, 'the reads a viewer may call');
      const reads = /\/(list_parameters|get_parameters|get_parameter_types|describe_parameters)$|^\/rosgate\/topic_stats$/;
      assert.deepEqual([...fox.services.keys()].filter((name) => !reads.test(name)), []);
      assert.ok(!fox.services.has('/add_two_ints') && ![...fox.services.keys()].some((n) => n.endsWith('/set_parameters')));
    } finally {
      await fox.close();
    }
  });

  test('an operator\'s token in the URL drives the turtle', async () => {
    const fox = new Fox(`${authUrl}?token=${encodeURIComponent(TOKENS.operator)}`);
    try {
      assert.ok(await drive(fox) > 0.4);
      assert.deepEqual(fox.statuses.filter((s) => s.level === 2), []);
    } finally {
      await fox.close();
    }
  });

  test('the session cookie of /login signs the connection in too', async () => {
    const login = await fetch(new URL('/login', authUrl.replace(/^ws/, 'http')), {
      method: 'POST', redirect: 'manual', body: new URLSearchParams({ token: TOKENS.operator, next: '/' }),
    });
    assert.equal(login.status, 303);
    const cookie = login.headers.get('set-cookie').split(';')[0];
    const fox = new Fox(authUrl, { Cookie: cookie });
    try {
      await fox.channel('/turtle1/cmd_vel');
      await fox.until(() => fox.services.size > 0, 'the services an operator may call');
    } finally {
      await fox.close();
    }
  });
});
