// Tablet-first layout: a code panel that folds away, a workspace that follows its box, and
// programs that open zoomed to fit (never smaller than blocks a finger can still drag).
/* global Blockly */
import { t } from '../i18n.js';

const CODE_KEY = 'rosgate.code';
export const PHONE = '(max-width: 820px)';

// `toggle`: the button that shows and hides the code panel (body[data-code] = shown | hidden).
export function bindLayout(workspace, toggle) {
  const setCode = (shown, remember = false) => {
    document.body.dataset.code = shown ? 'shown' : 'hidden';
    toggle.textContent = t(shown ? 'ide.code.hide' : 'ide.code.show');
    toggle.setAttribute('aria-expanded', String(shown));
    if (remember) try { localStorage.setItem(CODE_KEY, shown ? 'shown' : 'hidden'); } catch { /* private mode */ }
  };
  let saved = null;
  try { saved = localStorage.getItem(CODE_KEY); } catch { /* private mode */ }
  setCode(saved ? saved === 'shown' : !matchMedia(PHONE).matches);
  toggle.onclick = () => setCode(document.body.dataset.code !== 'shown', true);
  // the workspace's box changes with the code panel, a rotated tablet or a phone's page layout
  new ResizeObserver(() => Blockly.svgResize(workspace)).observe(workspace.getInjectionDiv());
}

// Zooms so the whole program shows, between `min` and `max` scale, its start top left.
export function fitProgram(workspace, { min = 0.5, max = 0.8 } = {}) {
  if (!workspace.getTopBlocks(false).length) return;
  workspace.zoomToFit();
  const scale = Math.min(max, Math.max(min, workspace.scale));
  if (scale !== workspace.scale) workspace.setScale(scale);
  const box = workspace.getBlocksBoundingBox();
  const view = workspace.getMetricsManager().getViewMetrics(true);
  const fits = box.right - box.left <= view.width && box.bottom - box.top <= view.height;
  if (fits) workspace.scrollCenter();
  else workspace.scroll(-(box.left * scale) + 16, -(box.top * scale) + 16);
}
