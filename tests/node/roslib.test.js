// Black-box tests of rosgate with npm roslib 2.x, the client most browser pages use.
import { after, before, test } from 'node:test';
import assert from 'node:assert/strict';
import { once } from 'node:events';
import { Action, Param, Ros, Service, Topic } from 'roslib';
import { call, startGateway, withTimeout } from './support.js';

let gateway;
let ros;

before(async () => {
  gateway = await startGateway();
  ros = new Ros({ url: gateway.url });
  await withTimeout(once(ros, 'connection'), 10000, 'connect');
});

after(async () => {
  ros?.close();
  await gateway?.stop();
});

test('Topic: publish and subscribe round trip', async () => {
  const topic = new Topic({ ros, name: '/node/chatter', messageType: 'std_msgs/msg/String' });
  const received = [];
  const all = new Promise((resolve) => {
    topic.subscribe((msg) => {
      received.push(msg.data);
      if (received.length === 5) resolve();
    });
  });
  const pub = new Topic({ ros, name: '/node/chatter', messageType: 'std_msgs/msg/String' });
  pub.advertise();
  for (let i = 0; i < 5; i++) pub.publish({ data: `hello ${i}` });
  await withTimeout(all, 5000, 'subscription');
  assert.deepEqual(received, [0, 1, 2, 3, 4].map((i) => `hello ${i}`));
  topic.unsubscribe();
});

test('Service: call /add_two_ints with no type (resolved from the graph)', async () => {
  const service = new Service({ ros, name: '/add_two_ints', serviceType: 'example_interfaces/srv/AddTwoInts' });
  const response = await call((ok, fail) => service.callService({ a: 19, b: 23 }, ok, fail));
  assert.deepEqual(response, { sum: 42 });
});

test('Service: a failing call reaches the failed callback', async () => {
  const service = new Service({ ros, name: '/no/such/service', serviceType: 'std_srvs/srv/Trigger' });
  const error = await call((ok, fail) => service.callService({}, () => fail(new Error('unexpected success')), ok));
  assert.match(String(error), /\/no\/such\/service/);
});

test('Service: a browser client can be the server', async () => {
  const server = new Service({ ros, name: '/node/add', serviceType: 'example_interfaces/srv/AddTwoInts' });
  await server.advertise((request, response) => {
    response.sum = request.a * 10 + request.b;
    return true;
  });
  const caller = new Service({ ros, name: '/node/add', serviceType: 'example_interfaces/srv/AddTwoInts' });
  // a server Service object does not call itself; use a fresh one on the same connection
  const response = await call((ok, fail) => caller.callService({ a: 4, b: 2 }, ok, fail));
  assert.deepEqual(response, { sum: 42 });
  await server.unadvertise();
});

test('Action: send a Fibonacci goal with feedback and result', async () => {
  const action = new Action({ ros, name: '/fibonacci', actionType: 'example_interfaces/action/Fibonacci' });
  const feedback = [];
  const result = await call((ok, fail) => action.sendGoal({ order: 5 }, ok, (fb) => feedback.push(fb), fail));
  assert.deepEqual(result, { sequence: [0, 1, 1, 2, 3, 5] });
  assert.ok(feedback.length >= 4, `feedback ${feedback.length}`);
  assert.deepEqual(feedback.at(-1).sequence, [0, 1, 1, 2, 3, 5]);
});

test('Action: cancel a running goal', async () => {
  const action = new Action({ ros, name: '/fibonacci', actionType: 'example_interfaces/action/Fibonacci' });
  let goalId;
  const outcome = call((ok, fail) => {
    let cancelled = false;
    goalId = action.sendGoal({ order: 40 }, ok, () => {
      if (!cancelled) {
        cancelled = true;
        action.cancelGoal(goalId);
      }
    }, fail);
  }, 10000, 'cancel');
  // roslib reports a non-succeeded result (canceled) through the failed callback
  const error = await outcome.then(() => 'succeeded', (e) => String(e));
  assert.match(error, /5|cancel/i);
});

test('getTopics, getServices, getNodes list the live graph', async () => {
  const topics = await call((ok, fail) => ros.getTopics(ok, fail));
  assert.ok(topics.topics.includes('/client_count'), JSON.stringify(topics));
  assert.equal(topics.types[topics.topics.indexOf('/client_count')], 'std_msgs/msg/Int32');
  const services = await call((ok, fail) => ros.getServices(ok, fail));
  assert.ok(services.includes('/add_two_ints'));
  const nodes = await call((ok, fail) => ros.getNodes(ok, fail));
  assert.ok(nodes.includes('/rosapi'));
});

test('getMessageDetails and decodeTypeDefs describe a type', async () => {
  const defs = await call((ok, fail) => ros.getMessageDetails('geometry_msgs/msg/Twist', ok, fail));
  const decoded = ros.decodeTypeDefs(defs);
  assert.deepEqual(Object.keys(decoded), ['linear', 'angular']);
  assert.deepEqual(Object.keys(decoded.linear), ['x', 'y', 'z']);
});

test('Param: get and set a node parameter', async () => {
  const param = new Param({ ros, name: '/fibonacci_action_server:step_interval' });
  assert.equal(await call((ok, fail) => param.get(ok, fail)), 0.05);
  await call((ok, fail) => param.set(0.06, ok, fail));
  assert.equal(await call((ok, fail) => param.get(ok, fail)), 0.06);
  await call((ok, fail) => param.set(0.05, ok, fail));
});
