// The text program's editor: CodeMirror 6 (vendor/codemirror.mjs, bundled by build.mjs) in
// Python or JavaScript, with line numbers, undo, search, bracket matching and indentation from
// its basic setup, completion and names checked against the live robot (completion.js), the
// running line and an error's line marked. A tablet's on-screen keyboard has no Tab key: the
// toolbar above the text indents, outdents, undoes and searches with a tap.
import {
  basicSetup, EditorState, StateField, StateEffect, Compartment, EditorView, Decoration, keymap, placeholder,
  python, pythonLanguage, javascript, javascriptLanguage, autocompletion, linter, lintGutter, setDiagnostics, openSearchPanel,
  indentMore, indentLess, undo, redo, indentWithTab, indentUnit,
} from '../../vendor/codemirror.mjs';
import { completionSource, lintSource } from './completion.js';
import { compileJs, ProgramError } from '../run/textrun.js';
import { t } from '../i18n.js';

const setMarks = StateEffect.define();   // {running: line|null, error: {line, message}|null}

// The running line and the error's line, as line decorations (data-line: the student's number).
const marks = StateField.define({
  create: () => ({ running: null, error: null, deco: Decoration.none }),
  update(value, tr) {
    let { running, error } = value;
    for (const e of tr.effects) if (e.is(setMarks)) ({ running, error } = { running, error, ...e.value });
    if (tr.docChanged && error) error = null;   // an edit: the error is being fixed
    const lines = tr.state.doc.lines;
    const ranges = [];
    const at = (n, cls, attrs = {}) => {
      if (!n || n < 1 || n > lines) return;
      const line = tr.state.doc.line(n);
      ranges.push(Decoration.line({ class: cls, attributes: { 'data-line': String(n), ...attrs } }).range(line.from));
    };
    at(running, 'cm-running-line');
    if (error) at(error.line, 'cm-error-line', { title: error.message });
    ranges.sort((a, b) => a.from - b.from);
    return { running, error, deco: Decoration.set(ranges) };
  },
  provide: (f) => EditorView.decorations.from(f, (v) => v.deco),
});

const LANGS = { python: [python, pythonLanguage], javascript: [javascript, javascriptLanguage] };

export class TextEditor extends EventTarget {
  // parent: the element; env: { graph(), ns() } for completion and names
  constructor(parent, env) {
    super();
    this.env = env;
    this.names = lintSource(() => this.lang, env);
    this.lang = 'python';
    this.language = new Compartment();
    this.tools = toolbar(this);
    parent.append(this.tools);
    const host = document.createElement('div');
    host.className = 'cm-host';
    parent.append(host);
    this.view = new EditorView({
      parent: host,
      state: this._state('', 'python'),
    });
  }

  _state(doc, lang, hint = '') {
    return EditorState.create({
      doc,
      extensions: [
        basicSetup,
        placeholder(hint),
        keymap.of([indentWithTab]),
        indentUnit.of(lang === 'python' ? '    ' : '  '),
        this.language.of(this._language(lang)),
        // nothing chosen until an arrow key or a tap: Enter at the end of a word is a new line
        autocompletion({ activateOnTyping: true, selectOnOpen: false }),
        linter((view) => this._diagnostics(view), { delay: 400 }),
        lintGutter(),
        marks,
        EditorView.lineWrapping,
        EditorView.updateListener.of((u) => {
          if (u.docChanged) this.dispatchEvent(new Event('change'));
        }),
      ],
    });
  }

  // the mode and, merged with its own completion (the program's names, keywords), the robot's
  _language(lang) {
    const [mode, language] = LANGS[lang];
    return [mode(), language.data.of({ autocomplete: completionSource(() => this.lang, this.env) })];
  }

  get text() { return this.view.state.doc.toString(); }

  // A new text (a program opened): undo history starts afresh.
  // `hint`: shown while the text is empty.
  load(text, lang, hint = '') {
    this.lang = lang;
    this.view.setState(this._state(text, lang, hint));
    this.tools.dataset.lang = lang;
  }

  focus() { this.view.focus(); }

  // The line a run is at (null: none).
  running(line) { this.view.dispatch({ effects: setMarks.of({ running: line ?? null }) }); }

  // An error at the student's line (null: none); the editor scrolls to it.
  error(line, message = '') {
    const n = Number(line) || null;
    const effects = [setMarks.of({ error: n ? { line: n, message } : null })];
    if (n && n <= this.view.state.doc.lines) {
      effects.push(EditorView.scrollIntoView(this.view.state.doc.line(n).from, { y: 'center' }));
    }
    this.view.dispatch({ effects });
    this.relint();
  }

  marks() { return this.view.state.field(marks); }

  // The lint: names the robot lacks (warnings), the error of the last run (in the gutter too), and
  // else a JavaScript syntax error.
  _diagnostics(view) {
    const out = this.names(view);
    const { error } = view.state.field(marks);
    if (error && error.line <= view.state.doc.lines) {
      const line = view.state.doc.line(error.line);
      out.push({ from: line.from, to: line.to, severity: 'error', source: 'run', message: error.message || 'error' });
    } else if (this.lang === 'javascript') {     // JavaScript's own parse, as the student types
      try { compileJs(view.state.doc.toString(), 'rosgate-lint.js'); } catch (e) {
        if (e instanceof ProgramError && e.line <= view.state.doc.lines) {
          const line = view.state.doc.line(e.line);
          out.push({ from: line.from, to: line.to, severity: 'error', source: 'syntax', message: e.message });
        }
      }
    }
    return out;
  }

  // The names on the graph changed, or a run marked an error: the lint again, now.
  relint() { this.view.dispatch(setDiagnostics(this.view.state, this._diagnostics(this.view))); }

  command(name) {
    const cmd = { indent: indentMore, outdent: indentLess, undo, redo, search: openSearchPanel }[name];
    cmd?.(this.view);
    if (name !== 'search') this.view.focus();
  }
}

// Buttons for what a hardware keyboard does with keys an on-screen keyboard lacks.
function toolbar(editor) {
  const bar = document.createElement('div');
  bar.className = 'text-tools';
  const buttons = [
    ['indent', '⇥', t('text.tool.indent')], ['outdent', '⇤', t('text.tool.outdent')],
    ['undo', '↶', t('text.tool.undo')], ['redo', '↷', t('text.tool.redo')], ['search', t('text.tool.find'), t('text.tool.search')],
  ];
  for (const [name, text, title] of buttons) {
    const b = document.createElement('button');
    b.type = 'button';
    b.dataset.cmd = name;
    b.textContent = text;
    b.title = title;
    b.setAttribute('aria-label', title);
    // keep the editor's focus (and the on-screen keyboard) while the button is pressed
    b.addEventListener('mousedown', (e) => e.preventDefault());
    b.onclick = () => editor.command(name);
    bar.append(b);
  }
  const lang = document.createElement('span');
  lang.className = 'text-lang';
  bar.append(lang);
  return bar;
}
