// A plain rosbridge teleop in Node with npm roslib: Topic.publish with no stamp, at 10 Hz while a
// key is held; on release it just stops sending (as most teleops do). For the home-link tests
// (tests/ide/test_home_link.py), one command per stdin line, one answer per stdout line:
//   hold X        publish linear.x = X every 100 ms
//   release       stop publishing
//   sync          a rosapi call on this connection: answered once everything sent before arrived
//   quit
// The first line out is "ready" once connected. Usage: node plain-driver.mjs URL TOPIC
import { createInterface } from 'node:readline';
import { Ros, Service, Topic } from 'roslib';

const [url, topic] = process.argv.slice(2);
const ros = new Ros({ url });
await new Promise((resolve, reject) => { ros.on('connection', resolve); ros.on('error', reject); });
const cmd = new Topic({ ros, name: topic, messageType: 'geometry_msgs/msg/Twist' });
const time = new Service({ ros, name: '/rosapi/get_time', serviceType: 'rosapi_msgs/srv/GetTime' });
let timer = null;
const say = (line) => process.stdout.write(`${line}\n`);
say('ready');

for await (const line of createInterface({ input: process.stdin })) {
  const [word, arg] = line.trim().split(/\s+/);
  if (word === 'hold') {
    clearInterval(timer);
    const msg = { linear: { x: Number(arg), y: 0, z: 0 }, angular: { x: 0, y: 0, z: 0 } };
    cmd.publish(msg);
    timer = setInterval(() => cmd.publish(msg), 100);
  } else if (word === 'release') {
    clearInterval(timer);
    timer = null;
  } else if (word === 'sync') {
    time.callService({}, () => say('synced'), (e) => say(`failed ${e}`));
  } else if (word === 'quit') {
    break;
  }
}
clearInterval(timer);
ros.close();
process.exit(0);
