// The IDE's Blockly workspace (categories along the top on a phone: the blocks get the width), its
// layout, the loose-block marks and the console whose lines lead to their block.
/* global Blockly */
import { Console } from './console.js';
import { bindLayout, PHONE } from './layout.js';
import { markLooseBlocks } from './loose.js';
import { buildToolbox } from '../blocks/toolbox.js';

const $ = (sel) => document.querySelector(sel);

export function mountWorkspace(ide) {
  const phone = matchMedia(PHONE).matches;
  const workspace = Blockly.inject($('#blockly'), {
    toolbox: buildToolbox(ide),
    horizontalLayout: phone,
    media: 'vendor/blockly/media/',
    renderer: 'zelos',
    trashcan: true,
    zoom: { controls: true, wheel: true, startScale: phone ? 0.7 : 0.8, maxScale: 2, minScale: 0.3 },
    move: { scrollbars: true, drag: true, wheel: false },
    grid: { spacing: 24, length: 2, colour: '#e4e6ee', snap: true },
  });
  ide.workspace = workspace;
  bindLayout(workspace, $('#code-toggle'));
  ide.looseBlocks = markLooseBlocks(workspace);
  ide.console = new Console($('#console-lines'), (id) => {
    const b = workspace.getBlockById(id);
    if (b) { workspace.centerOnBlock(id); Blockly.common.setSelected(b); }
  });
}
