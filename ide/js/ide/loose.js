// Loose blocks on the page: a value block on its own (generators/scope.js isLoose) is skipped by
// Run and by the generated code; here it is greyed and says why, until it is plugged in again.
/* global Blockly */
import { isLoose } from '../../generators/scope.js';
import { t } from '../i18n.js';

export const LOOSE_TEXT = t('loose.warning');
const WARNING_ID = 'loose';
const CLASS = 'rosgate-loose';

// Marks the workspace's loose blocks now and after every change; returns a function that
// lists the loose blocks (for Run's console line).
export function markLooseBlocks(workspace) {
  const marked = new Set();
  const update = () => {
    const loose = new Set(workspace.getTopBlocks(false).filter(isLoose));
    for (const id of [...marked]) {
      const b = workspace.getBlockById(id);
      if (b && loose.has(b)) continue;
      marked.delete(id);
      if (!b) continue;
      b.removeClass?.(CLASS);
      b.setWarningText(null, WARNING_ID);
    }
    for (const b of loose) {
      if (marked.has(b.id)) continue;
      marked.add(b.id);
      b.addClass?.(CLASS);
      b.setWarningText(LOOSE_TEXT, WARNING_ID);
    }
  };
  let timer = null;
  workspace.addChangeListener((e) => {
    if (e.isUiEvent && e.type !== Blockly.Events.BLOCK_DRAG) return;
    clearTimeout(timer);
    timer = setTimeout(update, 0);
  });
  update();
  return () => workspace.getTopBlocks(false).filter(isLoose);
}
