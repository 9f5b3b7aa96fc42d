// Text programs beside block programs: the page's mode (body[data-mode] = blocks | text), the
// editor (loaded at the first text program: CodeMirror is half a megabyte), "Edit as text" (the
// block program as readable Python or JavaScript that imports the runtime), and the downloads
// that run unchanged (the Python one with the runtime bundled on its import line).
import * as storage from './storage.js';
import { download } from '../views/download.js';
import { t, num } from '../i18n.js';

export const LANGS = { python: 'Python', javascript: 'JavaScript' };

// The Python text's first import of the runtime, prefixed (on the same line: the student's line
// numbers hold in a traceback) with a loader that makes the module from the runtime's text,
// so the file needs only roslibpy: `python3 program.py --url ws://HOST:PORT/`.
export function bundlePython(text, runtimeSource) {
  const lines = text.split('\n');
  const i = lines.findIndex((l) => /^\s*(from\s+rosgate_runtime\s+import\b|import\s+rosgate_runtime\b)/.test(l));
  if (i < 0) return text;
  const indent = /^\s*/.exec(lines[i])[0];
  const loader = 'import sys as _sys, types as _types; _rosgate = _types.ModuleType("rosgate_runtime"); '
    + `exec(compile(${JSON.stringify(runtimeSource)}, "rosgate_runtime.py", "exec"), _rosgate.__dict__); `
    + '_sys.modules["rosgate_runtime"] = _rosgate; ';
  lines[i] = indent + loader + lines[i].slice(indent.length);
  return lines.join('\n');
}

export function fileName(name, lang) {
  return `${storage.safeName(name).replace(/\W+/g, '_')}.${lang === 'python' ? 'py' : 'js'}`;
}

// A new text program's first lines: a short program that runs as it is.
export function starter(lang) {
  if (lang === 'python') {
    return [
      '"""A rosgate program in Python: ▶ Run runs it here; the .py download runs with roslibpy."""',
      'from rosgate_runtime import *',
      '',
      "print('driving turtle1 forward for a second')",
      "rt.publish(rt.ns('turtle1/cmd_vel'), 'geometry_msgs/msg/Twist', {'linear': {'x': 1.0}})",
      'rt.sleep(1)',
      "print('done')",
      '',
    ].join('\n');
  }
  return [
    '// A rosgate program in JavaScript: ▶ Run runs it here. `ros` (the page\'s connection to the',
    '// robot) and ROSLIB (roslib\'s classes) are in scope; await works at the top level.',
    "import { rt } from 'rosgate';",
    '',
    "rt.publish('/turtle1/cmd_vel', 'geometry_msgs/msg/Twist', { linear: { x: 1 } });",
    'await rt.sleep(1);',
    '',
  ].join('\n');
}

// The block program's text: the generators' code under a header that imports the runtime.
export function blocksAsText(ide, lang) {
  if (lang === 'python') return ide.generatePythonText();
  const body = ide.generateJs(false).trim();
  return [
    `// ${ide.programName}: a rosgate program in JavaScript, made from its blocks. ▶ Run runs it here;`,
    "// `ros` (the page's connection to the robot) and ROSLIB (roslib's classes) are in scope.",
    "import { rt } from 'rosgate';",
    '',
    body,
    '',
  ].join('\n');
}

// The page's text mode. `ide`: the page's object (console, graph, ns, runner …); `hooks`:
// { changed() after an edit, blocksMode() back to the blocks }.
export class TextMode {
  constructor(ide, hooks) {
    this.ide = ide;
    this.hooks = hooks;
    this.lang = null;            // null: the page shows blocks
    this.editor = null;
    this.pending = null;
    this.python = null;          // the Python loader's state shown in the editor's bar
  }

  // The words after the program's name when it runs (sys.argv[1:] of a Python program, as
  // `ros2 run PKG NODE 2 3` passes them), split as a shell splits them.
  get args() {
    const text = this.editor?.tools.querySelector('.text-args')?.value ?? '';
    return [...text.matchAll(/"([^"]*)"|'([^']*)'|(\S+)/g)].map((m) => m[1] ?? m[2] ?? m[3]);
  }

  // Python starts loading when a Python program opens (Pyodide's start is seconds on a 2-core
  // machine): the bar shows it loading, with the time so far, and then ready. The page's link
  // allows the longer silence a loaded machine shows meanwhile (pyrun.js, link.js heavy()).
  _preparePython(editor) {
    if (this.python) return;
    const bar = editor.tools;
    const state = Object.assign(document.createElement('span'), { className: 'text-python' });
    const args = Object.assign(document.createElement('input'), {
      className: 'text-args', type: 'text', placeholder: t('text.args'), title: t('text.args.title'),
    });
    args.setAttribute('aria-label', t('text.args.title'));
    bar.querySelector('.text-lang').before(args, state);
    const t0 = performance.now();
    const seconds = () => num((performance.now() - t0) / 1000, 1);
    const show = () => { state.textContent = t('text.python.loading.for', { s: seconds() }); };
    show();
    const ticker = setInterval(show, 200);
    this.python = import('../run/pyrun.js').then((py) => py.prepare()).catch(() => false).then((ok) => {
      clearInterval(ticker);
      state.textContent = ok ? t('text.python.ready', { s: seconds() }) : t('text.python.failed');
      state.dataset.state = ok ? 'ready' : 'failed';
      return ok;
    });
    state.dataset.state = 'loading';
  }

  get active() { return this.lang !== null; }

  async _editor() {
    if (this.editor) return this.editor;
    this.pending ??= import('./texteditor.js').then(({ TextEditor }) => {
      const editor = new TextEditor(document.querySelector('#text-editor'), {
        graph: () => this.ide.graph, ns: () => this.ide.ns ?? '',
      });
      editor.addEventListener('change', () => { if (!this.loading) this.hooks.changed(); });
      this.ide.graph?.addEventListener('change', () => editor.relint());
      this.editor = editor;
      this.ide.editor = editor;
      return editor;
    });
    return this.pending;
  }

  // Shows the text program `text` in `lang`; resolves once the editor holds it.
  async open(text, lang) {
    if (!LANGS[lang]) throw new Error(`no text programs in ${lang}`);
    const editor = await this._editor();
    this.lang = lang;
    this.loading = true;
    try { editor.load(text, lang, `${t('text.for.example')}\n\n${starter(lang)}`); } finally { this.loading = false; }
    document.body.dataset.mode = 'text';
    document.body.dataset.lang = lang;
    document.querySelector('#text-editor').hidden = false;
    document.querySelector('#blockly').hidden = true;
    document.querySelector('#download-py').textContent = lang === 'python' ? '.py' : '.js';
    document.querySelector('#download-py').title = t('text.download', { lang: LANGS[lang] });
    editor.tools.querySelector('.text-lang').textContent = LANGS[lang];
    if (lang === 'python') this._preparePython(editor);
    editor.tools.dataset.python = lang === 'python' ? 'shown' : 'hidden';
  }

  blocks() {
    this.lang = null;
    document.body.dataset.mode = 'blocks';
    delete document.body.dataset.lang;
    document.querySelector('#text-editor').hidden = true;
    document.querySelector('#blockly').hidden = false;
    document.querySelector('#download-py').textContent = '.py';
    document.querySelector('#download-py').title = t('text.download', { lang: LANGS.python });
    window.dispatchEvent(new Event('resize'));     // Blockly measures its box again
  }

  get text() { return this.editor?.text ?? ''; }

  program(name, robot) {
    return storage.makeTextProgram({ name, robot, lang: this.lang, text: this.text });
  }

  // The file that runs unchanged outside the page.
  download(name, runtimeSource) {
    const text = this.lang === 'python' ? bundlePython(this.text, runtimeSource) : this.text;
    download(fileName(name, this.lang), text, this.lang === 'python' ? 'text/x-python' : 'text/javascript');
  }
}
