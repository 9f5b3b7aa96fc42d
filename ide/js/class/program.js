// The teacher's read-only look at a student's program: the blocks as the student's IDE last
// reported them (NS/rosgate/program), in a Blockly workspace that cannot be edited; a text
// program as numbered lines, the running one marked.
/* global Blockly */
import '../blocks/fields.js';
import '../blocks/msgblock.js';
import { t } from '../i18n.js';
import { loadSchema, madeProblem, guardHelp } from '../blocks/blockcheck.js';

let workspace = null;
let defined = null;

async function defineBlocks() {
  if (!defined) {
    guardHelp();      // Help opens an http(s) page, nothing else
    defined = Promise.all([...['ros', 'turtlesim', 'rover'].map((n) => fetch(`blocks/${n}.json`).then((r) => r.json())), loadSchema()])
      .then(([...sets]) => { for (const set of sets.slice(0, 3)) for (const def of set.blocks) define(def, set.colour); });
  }
  return defined;
}

function define(def, colour) {
  const { rosgate: _spec, ...json } = def;
  if (Blockly.Blocks[json.type]) return;
  if (json.colour === undefined) json.colour = colour;
  Blockly.common.defineBlocksWithJsonArray([json]);
}

// Resolves to how much it shows: the blocks, or a text program's lines.
export async function showProgram(report, ns) {
  const dlg = document.querySelector('#dlg-program');
  document.querySelector('#program-title').textContent = `${ns} · ${report?.by?.name || t('class.student')} · ${report?.name ?? ''}`;
  document.querySelector('#program-close').onclick = () => dlg.close();
  dlg.showModal();
  const view = document.querySelector('#program-view');
  if (report?.program?.kind === 'text') return showText(report, view);
  view.hidden = false;
  document.querySelector('#program-text')?.remove();
  await defineBlocks();
  // a student's own blocks are data from outside this page: checked, and never in a block's place
  for (const custom of report?.program?.blocks ?? []) if (!madeProblem(custom)) define(custom.json, 330);
  if (!workspace) {
    workspace = Blockly.inject(document.querySelector('#program-view'), {
      readOnly: true, renderer: 'zelos', media: 'vendor/blockly/media/', sounds: false,
      zoom: { controls: true, wheel: true, startScale: 0.7, maxScale: 1 }, move: { scrollbars: true, drag: true, wheel: true },
    });
  }
  Blockly.svgResize(workspace);
  workspace.clear();
  try {
    Blockly.serialization.workspaces.load(report?.program?.workspace ?? {}, workspace);
    document.querySelector('#program-note').textContent = t('class.program.note');
  } catch (e) {
    document.querySelector('#program-note').textContent = t('class.program.failed', { error: e.message });
  }
  workspace.zoomToFit?.();
  return workspace.getAllBlocks(false).length;
}

// A text program: its lines, numbered, the line it ran at when reported marked.
function showText(report, view) {
  view.hidden = true;
  let pre = document.querySelector('#program-text');
  if (!pre) {
    pre = document.createElement('pre');
    pre.id = 'program-text';
    view.after(pre);
  }
  const lines = String(report.program.text ?? '').split('\n');
  const width = String(lines.length).length;
  pre.replaceChildren(...lines.map((text, i) => {
    const div = document.createElement('div');
    div.textContent = `${String(i + 1).padStart(width)}  ${text}`;
    if (report.line === i + 1 && report.state !== 'idle') div.className = 'running';
    return div;
  }));
  const lang = { python: 'Python', javascript: 'JavaScript' }[report.program.lang] ?? 'text';
  document.querySelector('#program-note').textContent = t('class.program.readonly', { lang });
  return lines.length;
}
