// The IDE page: registers the blocks, builds the workspace and wires the UI.
// Nothing else registers anything.
/* global Blockly */
import { Link } from '../link/link.js';
import { RosGraph, shared } from '../robot/graph.js';
import '../blocks/fields.js';
import '../blocks/msgblock.js';
import { gen as jsGen, registerSpec as registerJs } from '../../generators/javascript.js';
import { gen as pyGen, registerSpec as registerPy, setRuntimeSource } from '../../generators/python.js';
import { blockNode } from '../../generators/package.js';
import { mountPackages } from '../run/rospackages.js';
import { Runner } from '../run/runner.js';
import { Console } from './console.js';
import { WorldView } from '../views/worldview.js';
import * as storage from '../editors/storage.js';
import { download } from '../views/download.js';
import { MakeBlockDialog, registerMakeBlock } from '../blocks/makeblock.js';
import { whoami, showIdentity, abilities } from '../link/auth.js';
import { bindLayout, fitProgram, PHONE } from './layout.js';
import { DriverLease, bindDriverBadge, DRIVER_TOPIC } from '../robot/driver.js';
import { bindNamespace, CLAIM_SERVICE } from '../robot/robotns.js';
import { reportProgram } from './report.js';
import { RobotRuns } from '../lab/robotruns.js';
import { BlockSets } from '../blocks/blocksets.js';
import { withNamespace } from '../../runtime/util.js';
import { NameScope } from '../../generators/scope.js';
import { markLooseBlocks } from './loose.js';
import { mountRecorder } from '../lab/recorder.js';
import { mountBooking } from '../lab/booking.js';
import { TextMode, blocksAsText, bundlePython, starter, LANGS } from '../editors/textmode.js';
import { TextRunner } from '../run/textrun.js';
import { t, localized, pick, lang } from '../i18n.js';
import { mountExercise } from './exercise.js';
import { loadSchema, blockProblem, madeProblem, guardHelp } from '../blocks/blockcheck.js';
import { guard as foreignGuard, asLowered, signProgram, whose } from '../run/foreign.js';
import { api, ApiError } from '../link/api.js';

const $ = (sel) => document.querySelector(sel);
const getJson = (url) => api(url).catch((e) => { throw e instanceof ApiError ? new Error(`${url}: ${e.status}`) : e; });

// ---- blocks ----------------------------------------------------------------
// Every definition is data checked against the block schema (js/blocks/blockcheck.js) and never takes the
// place of a block already defined (a shared "controls_if" would have replaced the IDE's own).
function defineBlock(def, colour, namespaced = false, { made = false } = {}) {
  const why = blockProblem(def, def?.type ?? 'block', { made });
  if (why) throw new Error(why);
  if (Blockly.Blocks[def.type]) return;
  const { rosgate: found, ...json } = def;
  if (json.colour === undefined) json.colour = colour;
  Blockly.common.defineBlocksWithJsonArray([json]);
  const spec = found && namespaced ? { ...found, namespaced } : found;
  if (spec) { registerJs(json.type, spec); registerPy(json.type, spec); }
}

function toolboxEntries(set) {
  if (set.toolbox) return set.toolbox;
  return set.blocks.map((def) => {
    const inputs = {};
    for (const arg of (def.args0 ?? []).concat(def.args1 ?? [])) {
      if (arg.type === 'input_value' && set.shadows?.[arg.name]) inputs[arg.name] = { shadow: set.shadows[arg.name] };
    }
    return { kind: 'block', type: def.type, inputs };
  });
}

const ide = {
  sets: {},
  blockSets: new BlockSets(),   // the gateway's --blocks-dir: robots' sets, the class's shared blocks
  custom: [],            // "make a block" definitions saved with the program
  programName: 'my program',
  robot: 'any',
};
window.rosgateIde = ide;

function buildToolbox(base) {
  const contents = [...base.contents];
  for (const key of ['ros', 'turtlesim', 'rover']) {
    const set = ide.sets[key];
    contents.push({ kind: 'category', name: set.name, colour: String(set.colour), contents: toolboxEntries(set) });
  }
  contents.push(...ide.blockSets.categories(ide.ns, toolboxEntries));
  const mine = ide.custom.map((c) => ({ kind: 'block', type: c.json.type, inputs: c.toolboxInputs ?? {} }));
  const publish = ide.blockSets.publishable && ide.custom.length
    ? [{ kind: 'button', text: t('ide.blocks.publish'), callbackKey: 'publishBlocks' }] : [];
  contents.push({
    kind: 'category', name: t('ide.myblocks'), colour: '330',
    contents: [{ kind: 'button', text: t('ide.makeblock'), callbackKey: 'makeBlock' }, ...publish, ...mine],
  });
  return { kind: 'categoryToolbox', contents };
}

export function addCustomBlock(def) {
  const why = madeProblem(def);
  if (why) throw new Error(why);
  if (!ide.custom.some((c) => c.json.type === def.json.type)) ide.custom.push(def);
  if (!Blockly.Blocks[def.json.type]) defineBlock({ ...def.json, rosgate: def.spec }, 330, false, { made: true });
  ide.workspace?.updateToolbox(buildToolbox(ide.baseToolbox));
}

// The code panel shows the program; the runtime copied into the file is folded to one line.
function foldRuntime(code) {
  const a = code.indexOf('# --- rosgate runtime');
  const b = code.indexOf('# --- end of the rosgate runtime ---');
  if (a < 0 || b < 0) return code;
  const n = code.slice(a, b).split('\n').length;
  return `${code.slice(0, a)}# ... the rosgate runtime (${n} lines over roslibpy) is in the downloaded file ...${code.slice(b + 36)}`;
}

// ---- start -------------------------------------------------------------------
async function start() {
  const [ros_, turtlesim, rover, base, runtimePy] = await Promise.all([
    getJson('blocks/ros.json'), getJson('blocks/turtlesim.json'), getJson('blocks/rover.json'),
    getJson('toolbox.json'), fetch('runtime/rosgate_runtime.py').then((r) => r.text()), loadSchema(),
  ]);
  ide.sets = { ros: ros_, turtlesim, rover };
  ide.baseToolbox = base;
  setRuntimeSource(runtimePy);
  registerMakeBlock();
  guardHelp();               // Help opens an http(s) page, nothing else
  for (const set of Object.values(ide.sets)) for (const def of set.blocks) defineBlock(def, set.colour, set.namespaced);
  await ide.blockSets.load(defineBlock);

  const phone = matchMedia(PHONE).matches;    // categories along the top: the blocks get the width
  const workspace = Blockly.inject($('#blockly'), {
    toolbox: buildToolbox(base),
    horizontalLayout: phone,
    media: 'vendor/blockly/media/',
    renderer: 'zelos',
    trashcan: true,
    zoom: { controls: true, wheel: true, startScale: phone ? 0.7 : 0.8, maxScale: 2, minScale: 0.3 },
    move: { scrollbars: true, drag: true, wheel: false },
    grid: { spacing: 24, length: 2, colour: '#e4e6ee', snap: true },
  });
  ide.workspace = workspace;
  bindLayout(workspace, $('#code-toggle'));
  const looseBlocks = markLooseBlocks(workspace);

  const consoleView = new Console($('#console-lines'), (id) => {
    const b = workspace.getBlockById(id);
    if (b) { workspace.centerOnBlock(id); Blockly.common.setSelected(b); }
  });
  ide.console = consoleView;

  // connection
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
    onError: (text) => consoleView.warn(text),
    onState: () => banner(),
    onChange: (ns) => {
      ide.ns = ns;
      workspace.updateToolbox(buildToolbox(base));   // the block sets for this robot
      world.setTopic(withNamespace(ns, '/world/markers'));
      world.look((service, args) => graph.call(service, args));
      updateCode();
      consoleView.info(t('ide.ns.changed', { ns: ns || t('ide.ns.none') }));
    },
  });
  ide.ns = robotNs.get();
  if (ide.ns) workspace.updateToolbox(buildToolbox(base));   // the block sets for this robot
  ide.robotNs = robotNs;
  const world = new WorldView($('#world'), withNamespace(ide.ns, '/world/markers'));
  ide.world = world;
  const lease = new DriverLease();
  ide.lease = lease;
  bindDriverBadge(lease);
  robotNs.follow(lease);
  // the banner under the bar: what holds this robot (released, stopped, no robot), as on teleop
  const banner = () => {
    const why = robotNs.banner();
    $('#notice').textContent = why;
    $('#notice').hidden = !why;
  };
  lease.addEventListener('change', banner);
  lease.addEventListener('refused', () => {
    $('#driver').classList.add('refused');
    setTimeout(() => $('#driver').classList.remove('refused'), 3000);
  });
  graph.addEventListener('change', () => {
    if (graph.topics.has(DRIVER_TOPIC)) lease.watch();
    world.look((service, args) => graph.call(service, args));   // its markers and map, where published
    robotNs.claimable(graph.services.has(CLAIM_SERVICE));
    changedCode();            // names resolve against what the graph has
  });
  const url = $('#url');
  const params = new URLSearchParams(location.search);
  url.value = params.get('url') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`
    + (params.get('name') ? `?name=${encodeURIComponent(params.get('name'))}` : '');
  if (params.get('name')) $('.teleop-link').href = `teleop?name=${encodeURIComponent(params.get('name'))}`;
  const setStatus = (s, text) => {
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
    setStatus('connected', t('status.connected'));
    graph.setRos(ros);
    ide.robotRuns?.connected(ros);
    lease.attach(ros);
    robotNs.attach(ros);
    world.attach(ros);
    graph.refresh().catch((err) => consoleView.error(`rosapi: ${err.message}`));
  });
  link.addEventListener('lost', () => {
    setStatus('lost', t('status.lost'));
    runner.stop();
    textRunner.stop(t('text.why.link'));
  });
  link.addEventListener('state', (e) => { if (e.detail === 'connecting') setStatus('connecting', t('status.connecting')); });
  setInterval(() => { $('#link').textContent = link.describe(); }, 500);
  // a robot that starts after the page: its world is drawn once it publishes one
  setInterval(() => { if (ide.ros?.isConnected) world.look((service, args) => graph.call(service, args)); }, 10000);
  const connect = () => link.restart();
  $('#reconnect').onclick = connect;
  url.addEventListener('change', connect);

  // running
  const runner = new Runner(workspace, () => ide.ros, consoleView, () => ide.ns,
    { ready: () => graph.ready(), loose: looseBlocks });
  ide.runner = runner;
  // text programs (js/editors/textmode.js): the editor, and their runs in the page (js/run/textrun.js)
  const textRunner = new TextRunner(ide, { ready: () => graph.ready() });
  ide.textRunner = textRunner;
  const textMode = new TextMode(ide, { changed: () => { changed(); ide.report?.edited(); } });
  ide.textMode = textMode;
  ide.robotRuns = new RobotRuns(ide);
  ide.robotRuns.init();
  const runState = () => { document.body.dataset.run = textRunner.state !== 'idle' ? textRunner.state : runner.state; };
  runner.addEventListener('state', runState);
  textRunner.addEventListener('state', runState);
  lease.addEventListener('stop', () => {
    runner.stop();
    textRunner.stop(t('text.why.teacher'));
    consoleView.warn(t('ide.stopped.teacher', { robot: ide.ns || t('ide.this.robot') }));
  });
  ide.report = reportProgram(ide, { workspace, runners: [runner, textRunner], consoleEl: $('#console-lines') });
  $('#take').addEventListener('click', () => ide.report.clear());   // her Take: the tile's error is behind her
  document.body.dataset.run = 'idle';
  // a program drives only this person's robot, and not while the teacher's stop holds: said here
  // once per press, not as an error of the program's blocks
  const mayDrive = () => { const why = robotNs.whyNot(); if (why) consoleView.warn(why); return !why; };
  // a program from another person's link runs once its opener says so, without her admin rights
  ide.mayRun = foreignGuard(ide, {
    reconnect: () => new Promise((resolve) => { link.addEventListener('open', () => resolve(), { once: true }); link.restart(); }),
  });
  $('#run').onclick = async () => {
    if (!mayDrive() || !(await ide.mayRun())) return;
    if (textMode.active) textRunner.run(textMode.text, textMode.lang);
    else if (runner.state === 'paused') runner.resume();
    else runner.run();
  };
  $('#pause').onclick = () => runner.pause();
  $('#step').onclick = async () => mayDrive() && (await ide.mayRun()) && runner.step();
  $('#stop').onclick = () => { runner.stop(); textRunner.stop(t('text.why.button')); };

  // code panel, live
  let codeTimer = null;
  const changedCode = () => { clearTimeout(codeTimer); codeTimer = setTimeout(updateCode, 120); };
  const updateCode = () => {
    pyGen.programName = ide.programName;
    pyGen.namespace = ide.ns;
    try { $('#code-python').textContent = foldRuntime(pyGen.workspaceToCode(workspace)); } catch (e) { $('#code-python').textContent = `# ${e.message}`; }
    try { $('#code-js').textContent = jsGen.generate(workspace); } catch (e) { $('#code-js').textContent = `// ${e.message}`; }
    try {   // the ROS 2 node; its messages typed once the gateway's definitions are read
      const node = blockNode(workspace, { programName: ide.programName, namespace: ide.ns });
      $('#code-node').textContent = node.code;
      for (const key of node.missingTypes) graph.details(...key.split(':')).then(changedCode, () => {});
    } catch (e) { $('#code-node').textContent = `# ${e.message}`; }
  };
  const blocksPython = () => {
    pyGen.programName = ide.programName;
    pyGen.namespace = ide.ns;
    return pyGen.workspaceToCode(workspace);
  };
  // the program's Python that runs by itself (Run on robot, the library): a Python text program
  // with the runtime bundled on its import line
  ide.generatePython = () => {
    if (!textMode.active) return blocksPython();
    if (textMode.lang !== 'python') throw new Error(`this is a ${LANGS[textMode.lang]} program; only Python runs on the robot`);
    return bundlePython(textMode.text, runtimePy);
  };
  // the block program as a Python text program that imports the runtime
  ide.generatePythonText = () => {
    const indent = pyGen.INDENT;
    pyGen.importRuntime = true;
    pyGen.INDENT = '    ';          // the editor's indentation (PEP 8), not the code panel's two spaces
    try { return blocksPython(); } finally { pyGen.importRuntime = false; pyGen.INDENT = indent; }
  };
  ide.generateJs = (instrument = false) => jsGen.generate(workspace, { instrument });
  for (const btn of document.querySelectorAll('[data-tab]')) {
    btn.onclick = () => {
      for (const b of document.querySelectorAll('[data-tab]')) b.classList.toggle('on', b === btn);
      for (const p of document.querySelectorAll('.code')) p.hidden = p.id !== btn.dataset.tab;
    };
  }

  // programs
  const blockProgram = () => storage.makeProgram(workspace, { name: ide.programName, robot: ide.robot, blocks: ide.custom });
  const program = () => (textMode.active ? textMode.program(ide.programName, ide.robot) : blockProgram());
  ide.program = program;
  const named = (p) => {
    ide.programName = p.name || 'program';
    ide.robot = p.robot || 'any';
    $('#name').value = ide.programName;
  };
  // resolves once the program shows (a text program's editor loads at the first one)
  ide.loadProgram = async (p) => {
    storage.checkProgram(p);
    ide.foreign = null;                  // a program of the opener's own (a link's is marked after it opens)
    runner.stop();
    textRunner.stop();
    if (storage.isText(p)) {
      if (!textMode.active) storage.keepBlocks(blockProgram());   // the block program stays as it was
      await textMode.open(p.text, p.lang);
      named(p);
      ide.report?.clear();
      storage.autosave(program());
      return;
    }
    if (textMode.active) textMode.blocks();
    ide.custom = [];
    for (const def of p.blocks ?? []) addCustomBlock(def);
    workspace.updateToolbox(buildToolbox(ide.baseToolbox));
    workspace.clear();
    Blockly.serialization.workspaces.load(p.workspace, workspace);
    fitProgram(workspace);
    named(p);
    runner.clearErrors();
    ide.report?.clear();
    updateCode();
    storage.autosave(program());
  };
  $('#name').addEventListener('change', () => { ide.programName = $('#name').value.trim() || 'program'; changed(); });

  let saveTimer = null;
  const changed = () => {
    changedCode();
    clearTimeout(saveTimer);
    saveTimer = setTimeout(() => { storage.autosave(program()); ide.saved = (ide.saved ?? 0) + 1; }, 300);
  };
  workspace.addChangeListener((e) => { if (!e.isUiEvent) changed(); });

  const replacing = () => !(textMode.active ? textMode.text.trim() : workspace.getAllBlocks(false).length)
    || confirm(t('ide.new.confirm'));
  $('#new').onclick = async () => {
    if (!replacing()) return;
    ide.custom = [];
    await ide.loadProgram({ format: storage.FORMAT, name: 'my program', workspace: {} });
    workspace.updateToolbox(buildToolbox(base));
  };
  // a new text program: in Python a short one that runs as it is; in JavaScript empty (the editor
  // shows an example until the first key)
  const newText = (lang) => ide.loadProgram(storage.makeTextProgram({ name: 'my program', lang, text: lang === 'python' ? starter(lang) : '' }));
  $('#new-text').onchange = async () => {
    const lang = $('#new-text').value;
    $('#new-text').value = '';
    if (lang && replacing()) await newText(lang);
  };
  // "Edit as text": the block program in the code panel's language, as a text program of its own
  const editAsText = async (lang, name = `${ide.programName} ${lang}`) => {
    let text;
    try { text = blocksAsText(ide, lang); } catch (e) { consoleView.error(t('text.cannot.convert', { error: e.message })); return; }
    await ide.loadProgram(storage.makeTextProgram({ name, robot: ide.robot, lang, text }));
    consoleView.info(t('text.converted', { name: ide.programName, lang: LANGS[lang] }));
  };
  $('#edit-text').onclick = () => editAsText($('[data-tab].on')?.dataset.tab === 'code-js' ? 'javascript' : 'python');
  $('#to-blocks').onclick = async () => {
    const kept = storage.keptBlocks() ?? { format: storage.FORMAT, name: 'my program', workspace: {} };
    await ide.loadProgram(kept);
  };
  $('#download').onclick = () => {
    download(`${storage.safeName(ide.programName)}.json`, JSON.stringify(program(), null, 1));
  };
  $('#download-py').onclick = () => {
    if (textMode.active) { textMode.download(ide.programName, runtimePy); return; }
    download(`${storage.safeName(ide.programName).replace(/\W+/g, '_')}.py`, ide.generatePython(), 'text/x-python');
  };
  mountPackages(ide, { runtimePy, define: (def) => Blockly.Blocks[def.json.type] || defineBlock({ ...def.json, rosgate: def.spec }, 330) });
  $('#upload').onclick = async () => {
    const text = await storage.pickFile();
    if (!text) return;
    try { await ide.loadProgram(JSON.parse(text)); consoleView.info(t('ide.opened', { name: ide.programName })); } catch (e) { consoleView.error(t('ide.open.failed', { error: e.message })); }
  };
  $('#share').onclick = async () => {
    const p = program();
    const link = await storage.shareLink(p, await signProgram(JSON.stringify(p)));   // whose it is, signed
    ide.lastShareLink = link;
    history.replaceState(null, '', link);
    try { await navigator.clipboard.writeText(link); consoleView.info(t('ide.share.copied')); } catch {
      consoleView.info(t('ide.share.bar'));
    }
  };
  setupLibrary(program);
  await setupExamples();
  const maker = new MakeBlockDialog($('#dlg-make'), graph, addCustomBlock);
  workspace.registerButtonCallback('makeBlock', () => maker.open());
  ide.publishBlocks = () => ide.blockSets.publish(ide.custom).then(
    (n) => { consoleView.info(t('ide.blocks.published', { n })); workspace.updateToolbox(buildToolbox(ide.baseToolbox)); return n; },
    (e) => { consoleView.error(t('ide.blocks.publish.failed', { error: e.message })); throw e; });
  workspace.registerButtonCallback('publishBlocks', () => ide.publishBlocks().catch(() => {}));
  workspace.addChangeListener((e) => {   // a shared block in the program: saved with it
    if (e.type !== Blockly.Events.BLOCK_CREATE) return;
    for (const id of e.ids ?? []) {
      const made = ide.blockSets.sharedOf(workspace.getBlockById(id)?.type);
      if (made && !ide.custom.some((c) => c.json.type === made.json.type)) ide.custom.push(made);
    }
  });
  ide.makeBlock = maker;

  // the first program: a share link, else ?program= (an LMS activity's: NAME of the library,
  // example:NAME of the examples), else the autosave, else empty
  try {
    const shared_ = await storage.programFromHash();
    const query = new URLSearchParams(location.search);
    const byName = query.get('program');
    const lang = query.get('lang') in LANGS ? query.get('lang') : 'python';
    if (shared_) {
      await ide.loadProgram(shared_.program);
      const who = await whose(shared_.text, shared_.shared);
      if (!who.mine) ide.foreign = { ...who, confirmed: false };     // another person's: asked before it runs
    } else if (byName) {
      await ide.loadProgram(await programNamed(byName));
      // a text exercise (the LMS's deep link): a block program written as text in `lang`
      if (query.get('mode') === 'text' && !textMode.active) await editAsText(lang, ide.programName);
    } else if (query.get('mode') === 'text') await newText(lang);     // ?mode=text&lang=python|javascript
    else { const saved = storage.loadAutosave(); if (saved) await ide.loadProgram(saved); }
  } catch (e) { consoleView.error(t('ide.program.failed', { error: e.message })); }
  // ?exercise=ID: its start program and the bar's "Start attempt" (the gateway checks the goal)
  await mountExercise(ide, { runners: [runner, textRunner], runButton: $('#run'), say: (m) => consoleView.info(m) })
    .catch((e) => consoleView.error(t('ide.program.failed', { error: e.message })));
  updateCode();
  // with --auth: who is signed in decides whether the page connects and what it offers
  const me = await whoami();
  ide.me = me;
  showIdentity(me, { signin: $('#signin'), who: $('#who'), whoName: $('#who-name'), whoRole: $('#who-role') },
    { run: [$('#run'), $('#step'), $('#pause'), $('#run-robot')], save: [$('#library-save')] });
  if (me.signedIn) connect();
  else {
    setStatus('signin', t('status.signin'));
    consoleView.error(t('ide.needs.token'));
  }
  ide.ready = true;
  document.body.dataset.ready = 'true';
}

async function programNamed(name) {
  const example = name.startsWith('example:');
  const file = example ? name.slice(8) : name;
  if (!/^[A-Za-z0-9_-][A-Za-z0-9 _-]{0,63}$/.test(file)) throw new Error(`no program called ${name}`);
  return api(example ? `examples/${file}.json` : `api/programs/${encodeURIComponent(file)}`).catch((e) => {
    throw e instanceof ApiError ? new Error(`${name}: ${e.status} ${e.statusText}`) : e;
  });
}

function setupLibrary(program) {
  const dlg = $('#dlg-library');
  const list = $('#library-list');
  const refresh = async () => {
    list.replaceChildren();
    let items = [];
    // with --auth each signed-in name has a space of its own; an admin sees everyone's
    const me = ide.me ?? { auth: false, signedIn: true };
    const space = $('#library-space');
    space.hidden = !me.auth;
    space.textContent = !me.signedIn ? t('lib.signin')
      : abilities(me).everyone ? t('lib.everyone')
        : t(abilities(me).save ? 'lib.yours' : 'lib.yours.viewer', { name: me.name });
    try { items = await storage.library.list(); } catch (e) { list.textContent = t('lib.unavailable', { error: e.message }); return; }
    for (const item of items) {
      const li = document.createElement('li');
      Object.assign(li.dataset, { name: item.name, owner: item.owner ?? '' });   // js/run/rospackages.js ticks it
      const open = document.createElement('button');
      const who = item.owner && item.owner !== me.name ? `${item.owner} / ` : '';
      open.textContent = `${who}${item.name}`;
      open.className = 'lib-open';
      open.dataset.owner = item.owner ?? '';
      open.onclick = async () => {
        try { await ide.loadProgram(await storage.library.load(item.name, item.owner)); dlg.close(); } catch (e) { ide.console.error(e.message); }
      };
      const del = document.createElement('button');
      del.textContent = '🗑';
      del.title = t('lib.delete.title', { name: `${who}${item.name}` });
      del.disabled = !abilities(me).save;
      del.onclick = async () => {
        if (!confirm(t('lib.delete.confirm', { name: `${who}${item.name}` }))) return;
        try { await storage.library.remove(item.name, item.owner); } catch (e) { ide.console.error(t('lib.delete.failed', { error: e.message })); }
        refresh();
      };
      li.append(open, del);
      list.append(li);
    }
    if (!items.length) list.textContent = t('lib.empty');
  };
  $('#library').onclick = () => { dlg.showModal(); refresh(); };
  $('#library-save').onclick = async () => {
    const name = storage.safeName($('#name').value);
    let python = null;
    const js = ide.textMode.active && ide.textMode.lang === 'javascript';   // runs in the page only
    if (!js) try { python = ide.generatePython(); } catch (e) {
      ide.console.error(t('lib.nopython', { error: e.message }));
    }
    try {
      await storage.library.save(name, program(), python);
      ide.console.info(t('lib.saved', { name }));
      refresh();
    } catch (e) { ide.console.error(t('lib.save.failed', { error: e.message })); }
  };
  $('#library-close').onclick = () => dlg.close();
}

// An example in the reader's language: its name, its about and its blocks' comments (by block id;
// examples/make_examples.py writes them), which the generated code carries as comments too.
export function localizeExample(program) {
  const words = program.translations?.[pick([lang], Object.keys(program.translations ?? {}))];
  if (!words) return program;
  const out = structuredClone(program);
  out.name = words.name || out.name;
  out.about = words.about || out.about;
  const visit = (node) => {
    if (!node || typeof node !== 'object') return;
    if (typeof node.id === 'string' && node.icons?.comment && words.comments?.[node.id]) node.icons.comment.text = words.comments[node.id];
    for (const value of Object.values(node)) visit(value);
  };
  visit(out.workspace);
  return out;
}

async function setupExamples() {
  const menu = $('#examples');
  let index = [];
  try { index = (await getJson('examples/index.json')).examples; } catch { /* no examples served */ }
  ide.examples = index;
  for (const ex of index) {
    const opt = document.createElement('option');
    opt.value = ex.file;
    opt.textContent = `${localized({ en: ex.title, ...ex.titles })} (${ex.robot})`;
    menu.append(opt);
  }
  menu.onchange = async () => {
    const file = menu.value;
    menu.value = '';
    if (!file) return;
    try {
      await ide.loadProgram(localizeExample(await getJson(`examples/${file}`)));
      ide.console.info(t('ide.example.loaded', { name: ide.programName }));
    } catch (e) { ide.console.error(t('ide.example.failed', { error: e.message })); }
  };
}

// the page's one module: the bar's Rec and Booking first (as the page lays them out), then the IDE
mountRecorder();
mountBooking();
start().catch((e) => {
  document.body.dataset.ready = 'error';
  console.error(e);
  const el = document.querySelector('#console-lines');
  if (el) el.textContent = t('ide.failed', { error: e.message });
});
