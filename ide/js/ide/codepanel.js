// The code panel, live: the program as Python, JavaScript and a ROS 2 node (its messages typed once
// the gateway's definitions are read); and the program's code for the library, the downloads and
// runs (ide.generatePython, ide.generatePythonText, ide.generateJs).
import { gen as jsGen } from '../../generators/javascript.js';
import { gen as pyGen } from '../../generators/python.js';
import { blockNode } from '../../generators/package.js';
import { bundlePython, LANGS } from '../editors/textmode.js';

const $ = (sel) => document.querySelector(sel);

// The runtime copied into the file is folded to one line.
function foldRuntime(code) {
  const a = code.indexOf('# --- rosgate runtime');
  const b = code.indexOf('# --- end of the rosgate runtime ---');
  if (a < 0 || b < 0) return code;
  const n = code.slice(a, b).split('\n').length;
  return `${code.slice(0, a)}# ... the rosgate runtime (${n} lines over roslibpy) is in the downloaded file ...${code.slice(b + 36)}`;
}

export function mountCode(ide) {
  const { workspace, graph, textMode } = ide;
  let codeTimer = null;
  ide.changedCode = () => { clearTimeout(codeTimer); codeTimer = setTimeout(ide.updateCode, 120); };
  ide.updateCode = () => {
    pyGen.programName = ide.programName;
    pyGen.namespace = ide.ns;
    try { $('#code-python').textContent = foldRuntime(pyGen.workspaceToCode(workspace)); } catch (e) { $('#code-python').textContent = `# ${e.message}`; }
    try { $('#code-js').textContent = jsGen.generate(workspace); } catch (e) { $('#code-js').textContent = `// ${e.message}`; }
    try {   // the ROS 2 node; its messages typed once the gateway's definitions are read
      const node = blockNode(workspace, { programName: ide.programName, namespace: ide.ns });
      $('#code-node').textContent = node.code;
      for (const key of node.missingTypes) graph.details(...key.split(':')).then(ide.changedCode, () => {});
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
    return bundlePython(textMode.text, ide.runtimePy);
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
}
