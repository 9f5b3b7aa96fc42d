// The IDE's blocks and toolbox: the built-in sets (blocks/*.json), the gateway's (--blocks-dir), the
// ones a person made ("My blocks"). Every definition is data checked against the block schema
// (js/blocks/blockcheck.js) and never takes the place of a block already defined (a shared
// "controls_if" would have replaced the IDE's own).
/* global Blockly */
import { registerSpec as registerJs } from '../../generators/javascript.js';
import { registerSpec as registerPy, setRuntimeSource } from '../../generators/python.js';
import { loadSchema, blockProblem, madeProblem, guardHelp } from './blockcheck.js';
import { api, ApiError } from '../link/api.js';
import { t } from '../i18n.js';

// A JSON file of the page's (blocks/…, examples/…): its body, or an error naming it.
export const getJson = (url) => api(url).catch((e) => { throw e instanceof ApiError ? new Error(`${url}: ${e.status}`) : e; });

export function defineBlock(def, colour, namespaced = false, { made = false } = {}) {
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

// The sets, the toolbox and the runtime the Python carries (ide.sets, ide.baseToolbox, ide.runtimePy),
// every block defined. (The made blocks' mutator is registered first: makeblock.js.)
export async function loadBlocks(ide) {
  const [ros, turtlesim, rover, base, runtimePy] = await Promise.all([
    getJson('blocks/ros.json'), getJson('blocks/turtlesim.json'), getJson('blocks/rover.json'),
    getJson('toolbox.json'), fetch('runtime/rosgate_runtime.py').then((r) => r.text()), loadSchema(),
  ]);
  ide.sets = { ros, turtlesim, rover };
  ide.baseToolbox = base;
  ide.runtimePy = runtimePy;
  setRuntimeSource(runtimePy);
  guardHelp();               // Help opens an http(s) page, nothing else
  for (const set of Object.values(ide.sets)) for (const def of set.blocks) defineBlock(def, set.colour, set.namespaced);
  await ide.blockSets.load(defineBlock);
}

export function buildToolbox(ide) {
  const contents = [...ide.baseToolbox.contents];
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

// The workspace's toolbox built again (a new robot's sets, a block made or published).
export function updateToolbox(ide) {
  ide.workspace?.updateToolbox(buildToolbox(ide));
}

// A made block (saved with the program, or just made): defined once, listed in "My blocks".
export function addCustomBlock(ide, def) {
  const why = madeProblem(def);
  if (why) throw new Error(why);
  if (!ide.custom.some((c) => c.json.type === def.json.type)) ide.custom.push(def);
  if (!Blockly.Blocks[def.json.type]) defineBlock({ ...def.json, rosgate: def.spec }, 330, false, { made: true });
  updateToolbox(ide);
}
