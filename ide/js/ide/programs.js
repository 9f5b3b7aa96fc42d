// The program in the editors: what it is (blocks or text), loading one (ide.loadProgram), the
// autosave, New, a new text program, "Edit as text" and back to the blocks, and Share (a link that
// carries the program, signed with whose it is).
/* global Blockly */
import * as storage from '../editors/storage.js';
import { fitProgram } from './layout.js';
import { blocksAsText, starter, LANGS } from '../editors/textmode.js';
import { signProgram } from '../run/foreign.js';
import { addCustomBlock, updateToolbox } from '../blocks/toolbox.js';
import { t } from '../i18n.js';

const $ = (sel) => document.querySelector(sel);

export function mountPrograms(ide) {
  const { workspace, runner, textRunner, textMode, console: consoleView } = ide;
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
    for (const def of p.blocks ?? []) addCustomBlock(ide, def);
    updateToolbox(ide);
    workspace.clear();
    Blockly.serialization.workspaces.load(p.workspace, workspace);
    fitProgram(workspace);
    named(p);
    runner.clearErrors();
    ide.report?.clear();
    ide.updateCode();
    storage.autosave(program());
  };
  $('#name').addEventListener('change', () => { ide.programName = $('#name').value.trim() || 'program'; ide.changed(); });

  let saveTimer = null;
  ide.changed = () => {
    ide.changedCode();
    clearTimeout(saveTimer);
    saveTimer = setTimeout(() => { storage.autosave(program()); ide.saved = (ide.saved ?? 0) + 1; }, 300);
  };
  workspace.addChangeListener((e) => { if (!e.isUiEvent) ide.changed(); });

  const replacing = () => !(textMode.active ? textMode.text.trim() : workspace.getAllBlocks(false).length)
    || confirm(t('ide.new.confirm'));
  $('#new').onclick = async () => {
    if (!replacing()) return;
    ide.custom = [];
    await ide.loadProgram({ format: storage.FORMAT, name: 'my program', workspace: {} });
    updateToolbox(ide);
  };
  // a new text program: in Python a short one that runs as it is; in JavaScript empty (the editor
  // shows an example until the first key)
  ide.newText = (lang) => ide.loadProgram(storage.makeTextProgram({ name: 'my program', lang, text: lang === 'python' ? starter(lang) : '' }));
  $('#new-text').onchange = async () => {
    const lang = $('#new-text').value;
    $('#new-text').value = '';
    if (lang && replacing()) await ide.newText(lang);
  };
  // "Edit as text": the block program in the code panel's language, as a text program of its own
  ide.editAsText = async (lang, name = `${ide.programName} ${lang}`) => {
    let text;
    try { text = blocksAsText(ide, lang); } catch (e) { consoleView.error(t('text.cannot.convert', { error: e.message })); return; }
    await ide.loadProgram(storage.makeTextProgram({ name, robot: ide.robot, lang, text }));
    consoleView.info(t('text.converted', { name: ide.programName, lang: LANGS[lang] }));
  };
  $('#edit-text').onclick = () => ide.editAsText($('[data-tab].on')?.dataset.tab === 'code-js' ? 'javascript' : 'python');
  $('#to-blocks').onclick = async () => {
    const kept = storage.keptBlocks() ?? { format: storage.FORMAT, name: 'my program', workspace: {} };
    await ide.loadProgram(kept);
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
}
