// /inspect: inside the robot, for any robot (its namespace, as the other pages pick it): its topics
// with their types, publishers, subscribers, rate and bandwidth (measured by the gateway for the
// rows in view); an echo of one topic; its nodes, what each publishes, subscribes, serves and
// its parameters (read, and set where the gateway allows); the graph drawn; the /rosout log; a
// plot of any numeric fields; a message published and a service called from forms built from
// their types. One Link (link.js), every op through the gateway's rules; parts in js/inspect/.
import { Link } from '../link/link.js';
import { bindNamespace, CLAIM_SERVICE } from '../robot/robotns.js';
import { whoami } from '../link/auth.js';
import { Wire } from './wire.js';
import { TopicList } from './topics.js';
import { Echo } from './echo.js';
import { RosoutLog } from './rosout.js';
import { Nodes } from './nodes.js';
import { Params } from './params.js';
import { GraphView } from './graphview.js';
import { Plot } from './plot.js';
import { Sender } from './send.js';
import { t } from '../i18n.js';

const $ = (s) => document.querySelector(s);
const params = new URLSearchParams(location.search);
const LISTS_EVERY = 5000;        // ms between reads of the graph's names (topics, services, nodes)
const GRAPH_EVERY = 10000;       // ms between drawings of the graph, while it is in view

function setStatus(s, text) { const el = $('#status'); el.dataset.state = s; el.textContent = text; document.body.dataset.connection = s; }

function notice(text) {
  $('#notice').textContent = text;
  $('#notice').hidden = !text;
}

const url = params.get('url') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`;
const link = new Link(url);
const wire = new Wire(link);
export const inspect = { link, wire, types: new Map() };   // the page's state (tests: tests/support/page_state.js)

const topics = new TopicList(wire, { root: $('#topics-card'), body: $('#topics tbody'), filter: $('#topics-filter'), count: $('#topics-count') });
const echo = new Echo(wire, { root: $('#echo-card'), topic: $('#echo-topic'), rate: $('#echo-rate'), pause: $('#echo-pause'),
  info: $('#echo-info'), tree: $('#echo-tree'), image: $('#echo-image') });
const log = new RosoutLog(wire, { root: $('#log-card'), list: $('#log'), level: $('#log-level'), node: $('#log-node'),
  search: $('#log-search'), count: $('#log-count') });
const nodes = new Nodes(wire, { root: $('#nodes-card'), list: $('#nodes'), details: $('#node-details'), title: $('#node-title'),
  filter: $('#nodes-filter'), count: $('#nodes-count') });
const paramsView = new Params(wire, { root: $('#params-box'), body: $('#params tbody'), info: $('#params-info') });
const graph = new GraphView(wire, { root: $('#graph-card'), box: $('#graph'), debug: $('#graph-debug'), zoomIn: $('#graph-in'),
  zoomOut: $('#graph-out'), info: $('#graph-info') });
const plot = new Plot(wire, { root: $('#plot-card'), chart: $('#plot'), topic: $('#plot-topic'), field: $('#plot-field'),
  add: $('#plot-add'), pause: $('#plot-pause'), clear: $('#plot-clear'), span: $('#plot-span'), csv: $('#plot-csv'),
  png: $('#plot-png'), legend: $('#plot-legend'), info: $('#plot-info') });
const sender = new Sender(wire, {
  pub: { root: $('#pub'), topic: $('#pub-topic'), type: $('#pub-type'), form: $('#pub-form'), send: $('#pub-send'), info: $('#pub-info') },
  call: { root: $('#call'), service: $('#call-service'), form: $('#call-form'), send: $('#call-send'), info: $('#call-info'), result: $('#call-result') },
});
Object.assign(inspect, { topics, echo, log, nodes, params: paramsView, graph, plot, sender });

// ---- what the parts show -----------------------------------------------------------------
function chooseTopic(topic, type) {
  topics.select(topic);
  echo.show(topic, type);
}
topics.addEventListener('choose', (e) => chooseTopic(e.detail.topic, e.detail.type));
nodes.addEventListener('topic', (e) => { chooseTopic(e.detail, inspect.types.get(e.detail) ?? ''); $('#echo-card').scrollIntoView({ block: 'nearest' }); });
nodes.addEventListener('node', (e) => { $('#params-box').hidden = false; paramsView.show(e.detail.node, e.detail.services); });
$('#echo-plot').addEventListener('click', () => {
  $('#plot-topic').value = echo.topic;
  plot.offerFields(echo.topic);
  $('#plot-card').scrollIntoView({ block: 'nearest' });
});
$('#echo-publish').addEventListener('click', () => {
  sender.choosePublish(echo.topic);
  $('#send-card').scrollIntoView({ block: 'nearest' });
});
$('#graph-refresh').addEventListener('click', () => graph.refresh());

// A live echo from the start, until the reader picks one: the first topic in view that says where
// the robot is (odometry, a pose), else one that carries a few messages a second (else any); not
// the log (its part is below) nor TF, nor one of kilobytes a second (a camera, a cloud: a phone's link).
const QUIET = new Set(['/rosout', '/parameter_events', '/tf', '/tf_static']);
const LIGHT = 20000;   // bytes a second
const STATES = ['nav_msgs/msg/Odometry', 'turtlesim/msg/Pose', 'geometry_msgs/msg/PoseStamped', 'sensor_msgs/msg/JointState'];
topics.addEventListener('measured', (e) => {
  if (echo.topic) return;
  const live = e.detail.filter((m) => m.rate > 0 && m.bandwidth >= 0 && m.bandwidth < LIGHT && !QUIET.has(m.topic));
  const state = live.find((m) => STATES.includes(inspect.types.get(m.topic)));   // where the robot is: it moves
  const first = state ?? live.find((m) => m.rate >= 2) ?? live[0];
  if (first) chooseTopic(first.topic, inspect.types.get(first.topic) ?? '');
});

// The graph's names, now and then: the lists, the datalists, the parts that pick from them.
async function readNames() {
  let got;
  try { got = await wire.call('/rosapi/topics'); } catch { return; }
  const types = new Map(got.topics.map((name, i) => [name, got.types[i]]));
  inspect.types = types;
  topics.setTopics(types);
  echo.setTopics(types);
  plot.setTopics(types);
  sender.setTopics(types);
  $('#topic-names').replaceChildren(...[...types.keys()].map((n) => new Option(n, n)));
  $('#type-names').replaceChildren(...[...new Set(types.values())].sort().map((n) => new Option(n, n)));
  const { services } = await wire.call('/rosapi/services').catch(() => ({ services: [] }));
  $('#service-names').replaceChildren(...services.map((n) => new Option(n, n)));
  $('#claim').hidden = !services.includes(CLAIM_SERVICE);   // a fleet: a student claims hers to set its parameters
  await nodes.refresh();
  document.body.dataset.ready = 'true';
}

const graphSeen = { on: false };
new IntersectionObserver((entries) => { graphSeen.on = entries.some((e) => e.isIntersecting); if (graphSeen.on) graph.refresh(); })
  .observe($('#graph-card'));
setInterval(() => { if (!document.hidden && wire.connected) readNames(); }, LISTS_EVERY);
setInterval(() => { if (graphSeen.on && !document.hidden && wire.connected) graph.refresh(); }, GRAPH_EVERY);

// ---- the robot's namespace and the connection ------------------------------------------------
const robotNs = bindNamespace({
  call: (service, args) => wire.call(service, args),
  onChange: (ns) => { for (const part of [topics, log, nodes, graph]) part.setNamespace(ns); if (graphSeen.on) graph.refresh(); },
  onError: notice,
});
for (const part of [topics, log, nodes, graph]) part.setNamespace(robotNs.get());
inspect.robotNs = robotNs;

link.addEventListener('state', (e) => {
  const s = e.detail;
  setStatus(s, t(s === 'connected' ? 'status.connected' : s === 'lost' ? 'status.lost' : 'status.connecting'));
});
link.addEventListener('open', () => {   // (the wire subscribes again by itself)
  readNames();
  if (graphSeen.on) graph.refresh();
});
setInterval(() => { $('#link').textContent = link.describe(); }, 250);
setStatus('connecting', t('status.connecting'));
log.start();
whoami().then((me) => {
  if (me.auth && me.signedIn) $('#role').textContent = t('inspect.role', { name: me.name ?? '', role: me.role });
  if (me.auth && !me.signedIn) notice(t('inspect.sign.in'));
});
link.start();
