// ROS 2 packages of the page's programs (generators/package.js): "ROS 2 package (.zip)" packages
// the program shown, blocks or text; the library dialog packages the programs ticked there, one
// entry point each and a launch file starting them all. A block program becomes the node of
// generators/node.js; its messages are typed from the gateway's definitions, read first (rosapi).
/* global Blockly */
import { zipSync, strToU8 } from '../../vendor/fflate.mjs';
import { blockNode, rosPackage } from '../../generators/package.js';
import { bundlePython } from '../editors/textmode.js';
import * as storage from '../editors/storage.js';
import { download } from '../views/download.js';
import { t } from '../i18n.js';

const ROUNDS = 3;   // reads of missing type definitions before the node is written with what is known

// The node of a block workspace, its message types read from the gateway first where they can be.
export async function nodeOf(ide, workspace, programName) {
  let node = blockNode(workspace, { programName, namespace: ide.ns ?? '' });
  for (let i = 0; i < ROUNDS && node.missingTypes.length && ide.graph; i += 1) {
    const asked = await Promise.allSettled(node.missingTypes.map((key) => {
      const [kind, type] = key.split(':');
      return ide.graph.details(kind, type);
    }));
    if (!asked.some((a) => a.status === 'fulfilled')) break;
    node = blockNode(workspace, { programName, namespace: ide.ns ?? '' });
  }
  return node;
}

// {name, code} of a saved program (the library's or the page's): null for a JavaScript one.
async function programCode(ide, program, define, runtimePy) {
  if (storage.isText(program)) {
    if (program.lang !== 'python') return null;
    return { name: program.name, code: bundlePython(program.text, runtimePy) };
  }
  for (const def of program.blocks ?? []) define(def);
  const ws = new Blockly.Workspace();
  try {
    Blockly.serialization.workspaces.load(program.workspace ?? {}, ws);
    return { name: program.name, code: (await nodeOf(ide, ws, program.name)).code };
  } finally { ws.dispose(); }
}

function downloadZip(name, files) {
  const zip = zipSync(Object.fromEntries(Object.entries(files).map(([p, text]) => [p, strToU8(text)])));
  download(`${storage.safeName(name)}.zip`, zip, 'application/zip');
}

/**
 * The package buttons. ide: the page's object (console, textMode, workspace, programName, graph);
 * define(def): registers a program's own block; runtimePy: the runtime's text (a roslibpy program's
 * package carries it on its import line).
 */
export function mountPackages(ide, { define, runtimePy }) {
  // the program shown
  ide.packageShown = async () => {
    const tm = ide.textMode;
    if (tm.active && tm.lang !== 'python') throw new Error(t('pkg.python.only'));
    const code = tm.active ? bundlePython(tm.text, runtimePy) : (await nodeOf(ide, ide.workspace, ide.programName)).code;
    return rosPackage(ide.programName, [{ name: ide.programName, code }]);
  };
  // the program shown as a ROS 2 node (a run on the graph takes it, js/lab/robotruns.js): a block
  // program's node, a Python program that imports rclpy as it is, null for any other
  ide.rosNode = async () => {
    const tm = ide.textMode;
    if (!tm.active) return (await nodeOf(ide, ide.workspace, ide.programName)).code;
    return tm.lang === 'python' && /^\s*(import rclpy\b|from rclpy(\.\w+)* import )/m.test(tm.text) ? tm.text : null;
  };
  document.querySelector('#download-ros2').onclick = async () => {
    try {
      const { files } = await ide.packageShown();
      downloadZip(ide.programName, files);
    } catch (e) { ide.console.error(t('pkg.failed', { error: e.message })); }
  };

  // several programs of the library: a tick beside each, and a button under the list
  const list = document.querySelector('#library-list');
  const button = Object.assign(document.createElement('button'), { id: 'library-package', textContent: t('pkg.library') });
  button.title = t('pkg.library.title');
  document.querySelector('#library-save').after(' ', button);
  const ticked = () => [...list.querySelectorAll('input.lib-pick:checked')].map((c) => c.closest('li'));
  const update = () => { button.disabled = !ticked().length; };
  new MutationObserver(() => {
    for (const li of list.querySelectorAll('li')) {
      if (li.querySelector('input.lib-pick') || !li.dataset.name) continue;
      const tick = Object.assign(document.createElement('input'), { type: 'checkbox', className: 'lib-pick' });
      tick.title = t('pkg.pick', { name: li.dataset.name });
      tick.setAttribute('aria-label', tick.title);
      tick.onchange = update;
      li.prepend(tick);
    }
    update();
  }).observe(list, { childList: true });
  update();
  ide.packageLibrary = async (picked) => {
    const programs = [];
    for (const { name, owner } of picked) {
      const program = await storage.library.load(name, owner || undefined);
      const code = await programCode(ide, program, define, runtimePy);
      if (code) programs.push(code); else ide.console.warn(t('pkg.skipped', { name }));
    }
    if (!programs.length) throw new Error(t('pkg.none'));
    const name = programs.length > 1 ? 'rosgate_programs' : programs[0].name;
    return rosPackage(name, programs);
  };
  button.onclick = async () => {
    try {
      const { pkg, files } = await ide.packageLibrary(ticked().map((li) => ({ name: li.dataset.name, owner: li.dataset.owner })));
      downloadZip(pkg, files);
    } catch (e) { ide.console.error(t('pkg.failed', { error: e.message })); }
  };
}
