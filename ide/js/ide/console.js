// The console under the code panel: log output, run markers and errors that point at blocks.
import { t } from '../i18n.js';
export class Console {
  constructor(el, onBlock) {
    this.el = el;
    this.onBlock = onBlock;
    this.max = 500;
  }

  _line(text, cls, blockId) {
    const div = document.createElement('div');
    div.className = `line ${cls}`;
    div.textContent = text;
    if (blockId) {
      const a = document.createElement('button');
      a.className = 'goto';
      a.textContent = t('console.show.block');
      a.onclick = () => this.onBlock(blockId);
      div.append(' ', a);
      div.dataset.block = blockId;
    }
    const box = this.follow();
    this.el.append(div);
    while (this.el.childElementCount > this.max) this.el.firstElementChild.remove();
    if (box && this.pinned) box.scrollTop = box.scrollHeight;   // the newest line in sight, unless the reader scrolled up
  }

  // Whether the console follows its newest line: until the reader scrolls up, and again once she
  // scrolls back down. Kept from her scrolling, not from where the box's end happens to be: a
  // banner that shows above the console shrinks the box, which moves its end without her; the
  // box then scrolls to its newest line again.
  follow() {
    const box = this.scroller();
    if (!box || this.box === box) return box;
    this.box = box;
    this.pinned = true;
    box.addEventListener('scroll', () => { this.pinned = box.scrollHeight - box.scrollTop - box.clientHeight < 24; });
    new ResizeObserver(() => { if (this.pinned) box.scrollTop = box.scrollHeight; }).observe(box);
    return box;
  }

  // The element that scrolls (the lines' box, #console): setting the lines' own scrollTop did nothing.
  scroller() {
    for (let el = this.el; el; el = el.parentElement) {
      if (/auto|scroll/.test(getComputedStyle(el).overflowY)) return el;
    }
    return null;
  }

  log(text, level) { this._line(text, level === 'error' ? 'error' : 'log'); }
  info(text) { this._line(text, 'info'); }
  // A note the student must read that is no error of her program (the teacher's stop, no robot).
  warn(text) { this._line(text, 'warn'); }
  error(text, blockId) { this._line(text, 'error', blockId); }
  clear() { this.el.replaceChildren(); }

  // The log lines only (what the program printed), for comparisons.
  logs() { return [...this.el.querySelectorAll('.line.log')].map((d) => d.textContent); }
}
