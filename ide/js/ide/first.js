// What the IDE opens with, once it is built: the first program (a share link, else ?program= (an
// LMS activity's: NAME of the library, example:NAME of the examples), else the autosave, else
// empty), the exercise (?exercise=ID), who is signed in (with --auth: whether the page connects and
// what it offers), then the connection; and the page says it is ready.
import * as storage from '../editors/storage.js';
import { LANGS } from '../editors/textmode.js';
import { whoami, showIdentity } from '../link/auth.js';
import { whose } from '../run/foreign.js';
import { mountExercise } from './exercise.js';
import { programNamed } from './library.js';
import { t } from '../i18n.js';

const $ = (sel) => document.querySelector(sel);

export async function openFirst(ide) {
  const { textMode, console: consoleView } = ide;
  try {
    const shared = await storage.programFromHash();
    const query = new URLSearchParams(location.search);
    const byName = query.get('program');
    const lang = query.get('lang') in LANGS ? query.get('lang') : 'python';
    if (shared) {
      await ide.loadProgram(shared.program);
      const who = await whose(shared.text, shared.shared);
      if (!who.mine) ide.foreign = { ...who, confirmed: false };     // another person's: asked before it runs
    } else if (byName) {
      await ide.loadProgram(await programNamed(byName));
      // a text exercise (the LMS's deep link): a block program written as text in `lang`
      if (query.get('mode') === 'text' && !textMode.active) await ide.editAsText(lang, ide.programName);
    } else if (query.get('mode') === 'text') await ide.newText(lang);     // ?mode=text&lang=python|javascript
    else { const saved = storage.loadAutosave(); if (saved) await ide.loadProgram(saved); }
  } catch (e) { consoleView.error(t('ide.program.failed', { error: e.message })); }
  // ?exercise=ID: its start program and the bar's "Start attempt" (the gateway checks the goal)
  await mountExercise(ide, { runners: [ide.runner, ide.textRunner], runButton: $('#run'), say: (m) => consoleView.info(m) })
    .catch((e) => consoleView.error(t('ide.program.failed', { error: e.message })));
  ide.updateCode();
  const me = await whoami();
  ide.me = me;
  showIdentity(me, { signin: $('#signin'), who: $('#who'), whoName: $('#who-name'), whoRole: $('#who-role') },
    { run: [$('#run'), $('#step'), $('#pause'), $('#run-robot')], save: [$('#library-save')] });
  if (me.signedIn) ide.connect();
  else {
    ide.setStatus('signin', t('status.signin'));
    consoleView.error(t('ide.needs.token'));
  }
  ide.ready = true;
  document.body.dataset.ready = 'true';
}
