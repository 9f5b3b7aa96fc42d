// The IDE page: registers the blocks, builds the workspace and wires the UI, one part after the
// other, each the mount of a module of its own (each uses what those before it put on `ide`).
// `ide` is the page's state, exported (for tests: tests/support/page_state.js).
// Nothing else registers anything.
import '../blocks/fields.js';
import '../blocks/msgblock.js';
import { BlockSets } from '../blocks/blocksets.js';
import { loadBlocks } from '../blocks/toolbox.js';
import { registerMakeBlock, mountMakeBlock } from '../blocks/makeblock.js';
import { mountWorkspace } from './workspace.js';
import { mountConnection } from './connection.js';
import { mountRunning } from './running.js';
import { mountCode } from './codepanel.js';
import { mountPrograms } from './programs.js';
import { mountLibrary } from './library.js';
import { openFirst } from './first.js';
import { mountRecorder } from '../lab/recorder.js';
import { mountBooking } from '../lab/booking.js';
import { t } from '../i18n.js';

export const ide = {
  sets: {},
  blockSets: new BlockSets(),   // the gateway's --blocks-dir: robots' sets, the class's shared blocks
  custom: [],            // "make a block" definitions saved with the program
  programName: 'my program',
  robot: 'any',
};

async function start() {
  registerMakeBlock();           // the made blocks' mutator, before any block is defined
  await loadBlocks(ide);         // the block sets, the toolbox, the runtime (js/blocks/toolbox.js)
  mountWorkspace(ide);           // Blockly, the layout, the console
  mountConnection(ide);          // the graph, the station, the world, the lease, the Link (not yet connected)
  mountRunning(ide);             // the runners, the text editor, runs on the robot, Run/Pause/Step/Stop
  mountCode(ide);                // the code panel and the program's generated code
  mountPrograms(ide);            // loading, autosave, new, text, share
  await mountLibrary(ide);       // downloads, upload, the library, the examples
  mountMakeBlock(ide);           // "make a block", publishing them
  await openFirst(ide);          // the first program, the exercise, who is signed in, the connection
}

// the page's one module: the bar's Rec and Booking first (as the page lays them out), then the IDE
ide.recorder = mountRecorder();
ide.booking = mountBooking();
start().catch((e) => {
  document.body.dataset.ready = 'error';
  console.error(e);
  const el = document.querySelector('#console-lines');
  if (el) el.textContent = t('ide.failed', { error: e.message });
});
