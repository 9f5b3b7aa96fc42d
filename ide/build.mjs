// Bundles the npm packages the pages import into vendor/ (generated, not committed).
import { build } from 'esbuild';
import { cpSync, mkdirSync, readFileSync, readdirSync, rmSync, writeFileSync } from 'node:fs';
import { gzipSync } from 'node:zlib';
import { join } from 'node:path';

const here = new URL('.', import.meta.url).pathname;
const vendor = join(here, 'vendor');
const nm = join(here, 'node_modules');
rmSync(vendor, { recursive: true, force: true });
mkdirSync(vendor, { recursive: true });

// ES modules: one self-contained file per package.
const bundles = {
  'roslib.mjs': "export * from 'roslib';",
  'nipplejs.mjs': "export { default } from 'nipplejs'; export * from 'nipplejs';",
  'uplot.mjs': "export { default } from 'uplot';",
  // the ROS 2 package download (generators/package.js): a zip made in the page
  'fflate.mjs': "export { zipSync, strToU8 } from 'fflate';",
  // an exercise's instructions (js/ide/exercise.js): Markdown, its HTML escaped (markdown-it's html: false)
  'markdown-it.mjs': "export { default } from 'markdown-it';",
  // one copy of three for the twin, with the orbit controls, the URDF loader built on it and
  // three's own mesh loaders for a description's STL, Collada and OBJ (+ MTL) files
  'three.mjs': "export * from 'three'; export { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js'; "
    + "export { default as URDFLoader } from 'urdf-loader'; "
    + "export { STLLoader } from 'three/examples/jsm/loaders/STLLoader.js'; "
    + "export { ColladaLoader } from 'three/examples/jsm/loaders/ColladaLoader.js'; "
    + "export { OBJLoader } from 'three/examples/jsm/loaders/OBJLoader.js'; "
    + "export { MTLLoader } from 'three/examples/jsm/loaders/MTLLoader.js';",
  // the text editor (js/editors/texteditor.js): CodeMirror 6 with its Python and JavaScript modes, loaded
  // only when a text program opens
  'codemirror.mjs': [
    "export { basicSetup } from 'codemirror';",
    "export { EditorState, StateField, StateEffect, Compartment } from '@codemirror/state';",
    "export { EditorView, Decoration, keymap, placeholder } from '@codemirror/view';",
    "export { python, pythonLanguage } from '@codemirror/lang-python';",
    "export { javascript, javascriptLanguage } from '@codemirror/lang-javascript';",
    "export { autocompletion, startCompletion, snippetCompletion } from '@codemirror/autocomplete';",
    "export { linter, lintGutter, setDiagnostics } from '@codemirror/lint';",
    "export { openSearchPanel } from '@codemirror/search';",
    "export { indentMore, indentLess, undo, redo, indentWithTab } from '@codemirror/commands';",
    "export { syntaxTree, indentUnit } from '@codemirror/language';",
  ].join('\n'),
};
// uPlot formats numbers with `new Intl.NumberFormat(navigator.language)` when its module is evaluated.
// WebKitGTK under the POSIX locale (LANG=C.UTF-8, usual in containers and CI) reports navigator.language
// 'C', which no Intl constructor accepts: the RangeError left uplot.mjs unevaluated, and with it the
// teleop page (dashboard.js imports it). A tag Intl refuses falls back to uPlot's own 'en-US'.
const UPLOT_LOCALE = "new Intl.NumberFormat(domEnv ? nav.language : 'en-US')";
const validLocale = {
  name: 'uplot-valid-locale',
  setup(b) {
    b.onLoad({ filter: /uplot[\\/]dist[\\/]uPlot\.esm\.js$/ }, ({ path }) => {
      const src = readFileSync(path, 'utf8');
      if (!src.includes(UPLOT_LOCALE)) throw new Error(`${path}: its number format line changed; see build.mjs`);
      return {
        contents: src.replace(UPLOT_LOCALE, "new Intl.NumberFormat(domEnv && (() => { try { "
          + "return Intl.getCanonicalLocales(nav.language).length; } catch { return false; } })() ? nav.language : 'en-US')"),
        loader: 'js',
      };
    });
  },
};

for (const [out, contents] of Object.entries(bundles)) {
  await build({
    plugins: [validLocale],
    stdin: { contents, resolveDir: here, loader: 'js' },
    bundle: true,
    format: 'esm',
    platform: 'browser',
    target: 'es2020',
    minify: true,
    legalComments: 'none',
    logLevel: 'warning',
    outfile: join(vendor, out),
  });
}

// Blockly's classic scripts define the globals Blockly, javascript and python.
const blockly = join(nm, 'blockly');
for (const f of ['blockly_compressed.js', 'blocks_compressed.js',
  'javascript_compressed.js', 'python_compressed.js']) {
  cpSync(join(blockly, f), join(vendor, 'blockly', f));
}
// Blockly's own messages in every language it has (the pages load the reader's: js/i18n.js), so
// a language added to i18n/ finds Blockly's words without a new build.
mkdirSync(join(vendor, 'blockly', 'msg'), { recursive: true });
for (const f of readdirSync(join(blockly, 'msg')).filter((n) => n.endsWith('.js'))) {
  cpSync(join(blockly, 'msg', f), join(vendor, 'blockly', 'msg', f));
}
cpSync(join(blockly, 'media'), join(vendor, 'blockly', 'media'), { recursive: true });
cpSync(join(nm, 'uplot', 'dist', 'uPlot.min.css'), join(vendor, 'uplot.min.css'));
// Pyodide's core files, loaded by the Python worker (ide/js/run/pyworker.js) from vendor/pyodide/, never a CDN:
// the loader (vendor/pyodide/pyodide.mjs, revalidated at each load: it names the version) and, under
// vendor/pyodide/VERSION/, the interpreter (wasm and its glue), the standard library and the package
// index. A versioned path never changes content, so the gateway lets browsers keep those files (and
// the WebAssembly compiled from them) without asking again (gateway/web/pages.py).
const pyodideVersion = JSON.parse(readFileSync(join(nm, 'pyodide', 'package.json'), 'utf8')).version;
const pyodideDir = join(vendor, 'pyodide', pyodideVersion);
cpSync(join(nm, 'pyodide', 'pyodide.mjs'), join(vendor, 'pyodide', 'pyodide.mjs'));
for (const f of ['pyodide.asm.mjs', 'pyodide.asm.wasm', 'python_stdlib.zip', 'pyodide-lock.json']) {
  cpSync(join(nm, 'pyodide', f), join(pyodideDir, f));
}
// the gateway sends this to browsers that take gzip (9.6 MB -> 3.5 MB), compressed once here
writeFileSync(join(pyodideDir, 'pyodide.asm.wasm.gz'),
  gzipSync(readFileSync(join(nm, 'pyodide', 'pyodide.asm.wasm')), { level: 9 }));
writeFileSync(join(vendor, 'README'), 'Generated by `npm run build`; do not edit.\n');
console.log('vendor/ built');
