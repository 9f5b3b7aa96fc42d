// The IDE's connection: the graph of the robot (and the names generic blocks write in the page's
// robot namespace, generators/scope.js), the station, the world view, the driver's lease, the
// banner and the status, and the Link (js/link/link.js) at the bar's address. Connects when
// ide.connect() is called (first.js: once the person may).
import { Link } from '../link/link.js';
import { RosGraph, shared } from '../robot/graph.js';
import { gen as jsGen } from '../../generators/javascript.js';
import { gen as pyGen } from '../../generators/python.js';
import { NameScope } from '../../generators/scope.js';
import { WorldView } from '../views/worldview.js';
import { DriverLease, bindDriverBadge, DRIVER_TOPIC } from '../robot/driver.js';
import { bindNamespace, CLAIM_SERVICE } from '../robot/robotns.js';
import { withNamespace } from '../../runtime/util.js';
import { asLowered } from '../run/foreign.js';
import { updateToolbox } from '../blocks/toolbox.js';
import { t } from '../i18n.js';

const $ = (sel) => document.querySelector(sel);

export function mountConnection(ide) {
  const graph = new RosGraph();
  shared.graph = graph;
  ide.graph = graph;
  // generic blocks' names are written in the page's robot namespace (a fleet's station) or as
  // they are, from what the live graph has (generators/scope.js)
  const scope = new NameScope({ ns: () => ide.ns ?? '', has: (kind, name) => graph.has(kind, name),
    types: (kind, type) => graph.cachedDetails(kind, type) });
  shared.scope = scope;
  jsGen.scope = scope;
  pyGen.scope = scope;
  const robotNs = bindNamespace({
    call: (service, args) => graph.call(service, args),
    onError: (text) => ide.console.warn(text),
    onState: () => ide.banner(),
    onChange: (ns) => {
      ide.ns = ns;
      updateToolbox(ide);   // the block sets for this robot
      world.setTopic(withNamespace(ns, '/world/markers'));
      world.look((service, args) => graph.call(service, args));
      ide.updateCode();
      ide.console.info(t('ide.ns.changed', { ns: ns || t('ide.ns.none') }));
    },
  });
  ide.ns = robotNs.get();
  if (ide.ns) updateToolbox(ide);   // the block sets for this robot
  ide.robotNs = robotNs;
  const world = new WorldView($('#world'), withNamespace(ide.ns, '/world/markers'));
  ide.world = world;
  const lease = new DriverLease();
  ide.lease = lease;
  bindDriverBadge(lease);
  robotNs.follow(lease);
  // the banner under the bar: what holds this robot (released, stopped, no robot), as on teleop
  ide.banner = () => {
    const why = robotNs.banner();
    $('#notice').textContent = why;
    $('#notice').hidden = !why;
  };
  lease.addEventListener('change', ide.banner);
  lease.addEventListener('refused', () => {
    $('#driver').classList.add('refused');
    setTimeout(() => $('#driver').classList.remove('refused'), 3000);
  });
  graph.addEventListener('change', () => {
    if (graph.topics.has(DRIVER_TOPIC)) lease.watch();
    world.look((service, args) => graph.call(service, args));   // its markers and map, where published
    robotNs.claimable(graph.services.has(CLAIM_SERVICE));
    ide.changedCode();            // names resolve against what the graph has
  });
  const url = $('#url');
  const params = new URLSearchParams(location.search);
  url.value = params.get('url') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`
    + (params.get('name') ? `?name=${encodeURIComponent(params.get('name'))}` : '');
  if (params.get('name')) $('.teleop-link').href = `teleop?name=${encodeURIComponent(params.get('name'))}`;
  ide.setStatus = (s, text) => {
    const el = $('#status');
    el.dataset.state = s;
    el.textContent = text;
    document.body.dataset.connection = s;
  };
  const link = new Link(() => asLowered(ide, url.value));   // as an operator once it runs another's program
  ide.link = link;
  link.addEventListener('open', (e) => {
    const ros = e.detail;
    ide.ros = ros;
    ide.setStatus('connected', t('status.connected'));
    graph.setRos(ros);
    ide.robotRuns?.connected(ros);
    lease.attach(ros);
    robotNs.attach(ros);
    world.attach(ros);
    graph.refresh().catch((err) => ide.console.error(`rosapi: ${err.message}`));
  });
  link.addEventListener('lost', () => {
    ide.setStatus('lost', t('status.lost'));
    ide.runner.stop();
    ide.textRunner.stop(t('text.why.link'));
  });
  link.addEventListener('state', (e) => { if (e.detail === 'connecting') ide.setStatus('connecting', t('status.connecting')); });
  setInterval(() => { $('#link').textContent = link.describe(); }, 500);
  // a robot that starts after the page: its world is drawn once it publishes one
  setInterval(() => { if (ide.ros?.isConnected) world.look((service, args) => graph.call(service, args)); }, 10000);
  ide.connect = () => link.restart();
  $('#reconnect').onclick = ide.connect;
  url.addEventListener('change', ide.connect);
}
