// roslib 2.x's Action against rosgate as against a ROS 2 graph: cancelAllGoals() goes through the
// action server's hidden /fibonacci/_action/cancel_goal service, a goal of another action type is
// refused, and rosapi lists the hidden names as ROS 2 does (only when asked by name).
//
// With ROSGATE_URL set, the gateway there is used (tests/backends/test_roslib_actions.py runs this
// file against the rclpy backend on a Jazzy graph, ROSGATE_FIB_TYPE naming its Fibonacci type);
// without it, a sim gateway is started here.
import { after, before, test } from 'node:test';
import assert from 'node:assert/strict';
import { once } from 'node:events';
import { Action, Ros } from 'roslib';
import { call, startGateway, withTimeout } from './support.js';

const fibType = process.env.ROSGATE_FIB_TYPE || 'example_interfaces/action/Fibonacci';
const otherType = 'action_tutorials_interfaces/action/Fibonacci';
let gateway;
let ros;

before(async () => {
  if (!process.env.ROSGATE_URL) gateway = await startGateway();
  ros = new Ros({ url: process.env.ROSGATE_URL || gateway.url });
  await withTimeout(once(ros, 'connection'), 10000, 'connect');
});

after(async () => {
  ros?.close();
  await gateway?.stop();
});

// A long Fibonacci goal: resolves `started` at its first feedback and `outcome` with what roslib
// reports at its end (a non-succeeded goal comes through the failed callback).
function longGoal(action) {
  let started;
  const first = new Promise((resolve) => { started = resolve; });
  const outcome = withTimeout(new Promise((resolve) => {
    action.sendGoal({ order: 46 }, (result) => resolve(`succeeded ${JSON.stringify(result)}`),
      () => started(), (error) => resolve(String(error)));
  }), 20000, 'goal result');
  return { started: withTimeout(first, 5000, 'first feedback'), outcome };
}

test('Action.cancelAllGoals() cancels every running goal, and their results say CANCELED', async () => {
  const action = new Action({ ros, name: '/fibonacci', actionType: fibType });
  const goals = [longGoal(action), longGoal(action)];
  await Promise.all(goals.map((g) => g.started));
  action.cancelAllGoals();
  for (const goal of goals) {
    const outcome = await goal.outcome;   // the result, not a timer: the goal ended as canceled
    assert.match(outcome, /^GoalError: Action was canceled: \{"sequence":\[0,1/, outcome);
    assert.ok(JSON.parse(outcome.slice(outcome.indexOf('{'))).sequence.length < 47, outcome);
  }
});

test('a goal of another action type is refused with an error naming both types', async () => {
  const action = new Action({ ros, name: '/fibonacci', actionType: otherType });
  const outcome = await call((ok, fail) => action.sendGoal({ order: 3 }, () => fail(new Error('accepted')),
    () => {}, ok), 10000, 'refusal');
  assert.match(String(outcome), /^GoalError: Action status unknown: /);
  assert.ok(String(outcome).includes(fibType) && String(outcome).includes(otherType), String(outcome));
});

test('rosapi lists the hidden names only when asked for them by name', async () => {
  const servers = await call((ok, fail) => ros.getActionServers(ok, fail));
  assert.ok(servers.includes('/fibonacci'), JSON.stringify(servers));
  const services = await call((ok, fail) => ros.getServices(ok, fail));
  assert.ok(services.length > 0 && !services.some((s) => s.includes('/_action/')), JSON.stringify(services));
  const topics = await call((ok, fail) => ros.getTopics(ok, fail));
  assert.ok(!topics.topics.some((t) => t.includes('/_action/')), JSON.stringify(topics));
  const cancelType = await call((ok, fail) => ros.getServiceType('/fibonacci/_action/cancel_goal', ok, fail));
  assert.equal(cancelType, 'action_msgs/srv/CancelGoal');
  const sendType = await call((ok, fail) => ros.getServiceType('/fibonacci/_action/send_goal', ok, fail));
  assert.equal(sendType, `${fibType}_SendGoal`);
  const statusType = await call((ok, fail) => ros.getTopicType('/fibonacci/_action/status', ok, fail));
  assert.equal(statusType, 'action_msgs/msg/GoalStatusArray');
});
