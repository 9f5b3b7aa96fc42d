// The program's files: the downloads (.json, .py or .js, a ROS 2 package: js/run/rospackages.js),
// opening one from the device, the library (the gateway's programs: each person's space with
// --auth) and the examples (in the reader's language). programNamed: a program of the library or
// the examples by name (?program=).
/* global Blockly */
import * as storage from '../editors/storage.js';
import { download } from '../views/download.js';
import { mountPackages } from '../run/rospackages.js';
import { abilities } from '../link/auth.js';
import { api, ApiError } from '../link/api.js';
import { defineBlock, getJson } from '../blocks/toolbox.js';
import { t, localized, pick, lang } from '../i18n.js';

const $ = (sel) => document.querySelector(sel);

export async function mountLibrary(ide) {
  $('#download').onclick = () => {
    download(`${storage.safeName(ide.programName)}.json`, JSON.stringify(ide.program(), null, 1));
  };
  $('#download-py').onclick = () => {
    if (ide.textMode.active) { ide.textMode.download(ide.programName, ide.runtimePy); return; }
    download(`${storage.safeName(ide.programName).replace(/\W+/g, '_')}.py`, ide.generatePython(), 'text/x-python');
  };
  mountPackages(ide, { runtimePy: ide.runtimePy, define: (def) => Blockly.Blocks[def.json.type] || defineBlock({ ...def.json, rosgate: def.spec }, 330) });
  $('#upload').onclick = async () => {
    const text = await storage.pickFile();
    if (!text) return;
    try { await ide.loadProgram(JSON.parse(text)); ide.console.info(t('ide.opened', { name: ide.programName })); } catch (e) { ide.console.error(t('ide.open.failed', { error: e.message })); }
  };
  setupLibrary(ide);
  await setupExamples(ide);
}

export async function programNamed(name) {
  const example = name.startsWith('example:');
  const file = example ? name.slice(8) : name;
  if (!/^[A-Za-z0-9_-][A-Za-z0-9 _-]{0,63}$/.test(file)) throw new Error(`no program called ${name}`);
  return api(example ? `examples/${file}.json` : `api/programs/${encodeURIComponent(file)}`).catch((e) => {
    throw e instanceof ApiError ? new Error(`${name}: ${e.status} ${e.statusText}`) : e;
  });
}

function setupLibrary(ide) {
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
      await storage.library.save(name, ide.program(), python);
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

async function setupExamples(ide) {
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
