// "Enough charge to get home?": from the rover's odometry and battery, the charge needed to drive
// back to where the page first saw it, along the path it drove (a loop it closed is not driven
// twice), at the consumption it measured so far (percentage points per metre, idle drain
// included), with a 25 % margin. Warns while there is still charge to turn back.
import { t, num } from '../i18n.js';
export const MARGIN = 1.25;        // needed x this
export const RESERVE = 10;         // % left over below which it warns
const STEP = 0.1;                  // m between kept path points
const NEAR = 0.3;                  // m: back on an earlier part of the path
const MIN_DRIVEN = 1.0;            // m before a consumption is measured

export class HomeEstimate {
  constructor(el) {
    this.el = el;
    this.path = [];                // [x, y, metres driven to here]
    this.driven = 0;
    this.startPct = null;
    this.pct = null;
  }

  odom(msg) {
    const { x, y } = msg.pose.pose.position;
    const last = this.path[this.path.length - 1];
    if (!last) { this.path.push([x, y, 0]); this.show(); return; }
    const d = Math.hypot(x - last[0], y - last[1]);
    if (d < STEP) return;
    this.driven += d;
    this.path.push([x, y, this.driven]);
    this.show();
  }

  battery(msg) {
    if (!Number.isFinite(msg.percentage)) return;
    this.pct = msg.percentage * 100;
    if (this.startPct === null && this.path.length) this.startPct = this.pct;
    this.show();
  }

  // metres back to the start along the driven path, from the first point near where it is now
  back() {
    const here = this.path[this.path.length - 1];
    if (!here) return 0;
    for (const [x, y, m] of this.path) {
      const d = Math.hypot(here[0] - x, here[1] - y);
      if (d < NEAR) return m + d;
    }
    return here[2];
  }

  estimate() {
    const back = this.back();
    if (this.pct === null || this.startPct === null || this.driven < MIN_DRIVEN || this.startPct <= this.pct) {
      return { back, level: '', need: null, have: this.pct };
    }
    const perMetre = (this.startPct - this.pct) / this.driven;
    const need = perMetre * back * MARGIN;
    const left = this.pct - need;
    return { back, need, have: this.pct, perMetre, level: left < RESERVE / 2 ? 'danger' : left < RESERVE ? 'warn' : 'ok' };
  }

  show() {
    if (!this.el) return;
    const e = this.estimate();
    this.el.dataset.level = e.level;
    if (e.need === null) {
      this.el.textContent = this.path.length ? t('home.measuring', { m: num(e.back, 1) }) : '';
      return;
    }
    this.el.textContent = t('home.estimate', { m: num(e.back, 1), need: num(e.need, 1), have: num(e.have, 0), say: t(`home.${e.level}`) });
  }
}
