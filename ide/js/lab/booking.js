// Booked slots (--booking) on the IDE, the teleop page and the teacher's /class: a "Booking"
// button in the page's #bar that shows the time left in this person's slot (warning at 5 minutes
// and at 1), and a dialog with the timetable in the browser's time zone, a form to book a slot
// and a Cancel button on one's own bookings (an admin's on every booking; an admin also books
// "for" a student by her name). HTTP only
// (/api/bookings); the gateway's clock decides, so the time left is counted from the "now" of
// its answers, whatever this machine's clock says. The IDE and teleop pages show the station of
// their #ns field ("free until" when the next slot is someone else's); /class (no #ns) shows
// every station. When every station is taken, "Queue for a free robot" puts this person in the
// walk-ins' line (/api/queue): the dialog shows the place and the estimated wait, and once the
// gateway seats them the page presses its own "Claim a robot". A gateway without --booking
// answers {"enabled": false}: the button then stays hidden.
import { t, tn, time, day as dayOf } from '../i18n.js';
import { api } from '../link/api.js';

const REFRESH = 10000;          // ms between looks at the timetable
const WARN = [300, 60];         // s left at which the page warns

const el = (tag, { dataset = {}, ...props } = {}, ...children) => {
  const e = Object.assign(document.createElement(tag), props);
  Object.assign(e.dataset, dataset);
  e.append(...children);
  return e;
};

// an error is an ApiError: its status says a refusal (e.status) from a failure
const bookings = (path = '', options = {}) => api(`/api/bookings${path}`, options);
const queueApi = (method) => api('/api/queue', { method });

export const clock = (s) => time(s * 1000, { hour: '2-digit', minute: '2-digit', second: '2-digit', hourCycle: 'h23' });
const day = (s) => dayOf(s * 1000);
export const left = (s) => (s >= 3600 ? t('booking.hours', { h: Math.floor(s / 3600), min: Math.floor((s % 3600) / 60) })
  : `${Math.floor(s / 60)}:${String(Math.floor(s % 60)).padStart(2, '0')}`);
const localInput = (s) => {   // a datetime-local value for epoch seconds, in the browser's zone
  const d = new Date(s * 1000);
  return new Date(d.getTime() - d.getTimezoneOffset() * 60000).toISOString().slice(0, 19);
};

export class Booking {
  constructor(bar) {
    this.data = null;             // the last GET /api/bookings
    this.offset = 0;              // gateway clock - this clock, in s
    this.warned = new Set();
    this.queue = null;            // the last GET /api/queue
    this.inLine = false;          // this page put its person in the walk-ins' line
    this.button = el('button', { id: 'booking', hidden: true, title: t('booking.title'), textContent: t('booking') });
    this.warning = el('span', { id: 'booking-warning', className: 'booking-warning', hidden: true, role: 'alert' });
    bar.append(el('span', { className: 'group booking' }, this.button, this.warning));
    this.station = el('select', { id: 'booking-station' });
    this.start = el('input', { id: 'booking-start', type: 'datetime-local', step: 1 });
    this.minutes = el('input', { id: 'booking-minutes', type: 'number', min: 0.05, step: 'any', size: 5 });
    // an admin books for a student: by name, offered from everyone who signed in (LMS launches too)
    this.people = el('datalist', { id: 'booking-people' });
    this.behalf = el('input', { id: 'booking-for', size: 10, placeholder: t('booking.me') });
    this.behalf.setAttribute('list', 'booking-people');
    this.behalfLabel = el('label', { hidden: true }, t('booking.for'), ' ', this.behalf, this.people);
    this.message = el('p', { id: 'booking-msg', className: 'booking-msg' });
    this.status = el('p', { id: 'booking-status' });
    this.table = el('div', { id: 'booking-table' });
    const book = el('button', { id: 'booking-book', textContent: t('booking.book'), onclick: () => this.book() });
    this.queueButton = el('button', { id: 'booking-queue', textContent: t('booking.queue'), onclick: () => this.toggleQueue() });
    this.queueText = el('span', { id: 'booking-queue-text' });
    const close = el('button', { textContent: t('page.close'), onclick: () => this.dialog.close() });
    this.zone = el('small', { textContent: t('booking.zone', { zone: Intl.DateTimeFormat().resolvedOptions().timeZone }) });
    this.dialog = el('dialog', { id: 'dlg-booking' },
      el('h3', { textContent: t('booking.heading') }), this.status, this.zone, this.table,
      el('p', { className: 'booking-form' }, el('label', {}, t('booking.station'), ' ', this.station), ' ',
        el('label', {}, t('booking.from'), ' ', this.start), ' ', el('label', {}, t('booking.minutes'), ' ', this.minutes), ' ', this.behalfLabel, ' ', book),
      this.message, el('p', { className: 'booking-queue' }, this.queueButton, ' ', this.queueText), el('p', {}, close));
    document.body.append(this.dialog);
    this.button.onclick = () => { this.dialog.showModal(); this.refresh(); };
    this.station.onchange = () => this.render();
  }

  now() { return Date.now() / 1000 + this.offset; }

  // The page's robot station ('' on /class, or a page with no robot yet).
  namespace() {
    const input = document.querySelector('#ns');
    if (!input) return '';
    const top = input.value.trim().split('/').filter(Boolean)[0];
    return top ? `/${top}` : '';
  }

  async refresh() {
    try {
      const data = await bookings('?from=' + (Date.now() / 1000 + this.offset - 3600));
      if (!data.enabled) { this.button.hidden = true; return false; }
      this.offset = data.now - Date.now() / 1000;
      this.data = data;
      this.button.hidden = false;
      this.render();
      await this.pollQueue();
    } catch (e) {
      if (e.status === 404) { this.button.hidden = true; return false; }
      this.say(t('booking.read.failed', { error: e.message }), true);
    }
    return true;
  }

  // The walk-ins' line: join or leave it; seated at a free station, the page claims it.
  async toggleQueue() {
    try {
      const joining = !this.inLine;
      const q = await queueApi(joining ? 'POST' : 'DELETE');
      this.inLine = joining;
      this.showQueue(q);
    } catch (e) { this.say(t('booking.queue.failed', { error: e.message }), true); }
  }

  async pollQueue() {
    try { this.showQueue(await queueApi('GET')); } catch { /* the next refresh tries again */ }
  }

  showQueue(q) {
    this.queue = q;
    if (q.place) this.inLine = true;
    this.queueButton.textContent = t(this.inLine && !q.seated ? 'booking.leave' : 'booking.queue');
    this.queueButton.hidden = Boolean(q.station) && !q.place;
    const wait = q.wait === null || q.wait === undefined ? t('booking.unknown') : left(q.wait);
    this.queueText.textContent = q.place ? t('booking.place', { place: q.place, queued: q.queued, wait })
      : q.seated ? t('booking.seated', { ns: q.seated }) : q.queued ? t('booking.waiting', { n: q.queued }) : '';
    if (q.seated && this.inLine && !q.place) {     // seated from the line: this page takes its robot
      this.inLine = false;
      this.say(t('booking.turn', { ns: q.seated }));
      document.querySelector('#claim')?.click();
    }
  }

  say(text, error = false) {
    this.message.textContent = text;
    this.message.classList.toggle('error', error);
  }

  // This person's booking whose slot is on now, else null.
  current() {
    const now = this.now();
    return this.data?.bookings.find((b) => b.mine && b.start <= now && now < b.end) || null;
  }

  render() {
    const d = this.data;
    if (!d) return;
    const ns = this.namespace();
    const chosen = this.station.value || ns || d.stations[0] || '';
    this.station.replaceChildren(...d.stations.map((s) => new Option(s, s, false, s === chosen)));
    this.minutes.max = d.slot / 60;
    if (!this.minutes.value) this.minutes.value = String(Math.min(d.slot / 60, 15));
    if (!this.start.value) this.start.value = localInput(Math.ceil(this.now() / 60) * 60);
    const now = this.now();
    const shown = ns ? [ns] : d.stations;
    const admin = d.role === 'admin' || d.role === null;
    this.behalfLabel.hidden = d.role !== 'admin';
    if (d.role === 'admin' && !this.peopleAsked) this.loadPeople();
    this.table.replaceChildren(...shown.map((station) => {
      const rows = d.bookings.filter((b) => b.station === station && b.end > now - 60);
      const items = rows.map((b) => el('li', { className: `${b.mine ? 'mine' : ''}${b.start <= now && now < b.end ? ' on' : ''}`, dataset: { id: b.id } },
        `${day(b.start)} ${clock(b.start)}–${clock(b.end)} ${b.name}${b.start <= now && now < b.end ? ` ${t('booking.now')}` : ''} `,
        ...(b.mine || admin ? [el('button', { className: 'booking-cancel', textContent: t('page.cancel'), onclick: () => this.cancel(b) })] : [])));
      return el('section', { className: 'booking-station', dataset: { station } },
        el('h4', { textContent: `${station}: ${this.free(station)}` }),
        items.length ? el('ul', {}, ...items) : el('p', { textContent: t('booking.none') }));
    }));
    this.tick();
  }

  // "free until 10:30 (alice)", "alice's slot until 10:15", "free".
  free(station) {
    const now = this.now();
    const rows = (this.data?.bookings || []).filter((b) => b.station === station && b.end > now);
    const on = rows.find((b) => b.start <= now);
    if (on) return on.mine ? t('booking.yours.until', { at: clock(on.end) }) : t('booking.theirs.until', { who: on.name, at: clock(on.end) });
    const next = rows.sort((a, b) => a.start - b.start)[0];
    return next ? t('booking.free.until', { at: clock(next.start), who: next.mine ? t('driver.you') : next.name }) : t('station.free');
  }

  // Once a second: the time left in this person's slot, the warnings, the end.
  tick() {
    const slot = this.current();
    const ns = this.namespace();
    if (!slot) {
      const free = ns ? this.free(ns) : t('station.free');   // a walk-in's station: until when it is theirs
      this.button.textContent = free === t('station.free') ? t('booking') : `${t('booking')} · ${ns} ${free}`;
      this.button.classList.remove('on');
      this.warning.hidden = true;
      this.status.textContent = ns ? `${ns}: ${this.free(ns)}` : '';
      return;
    }
    const rest = Math.max(0, slot.end - this.now());
    this.button.textContent = t('booking.slot.left', { ns: slot.station, left: left(rest) });
    this.button.classList.add('on');
    this.status.textContent = t('booking.slot.ends', { ns: slot.station, at: clock(slot.end), left: left(rest) });
    const at = WARN.filter((w) => rest <= w).pop();
    if (at !== undefined) {
      this.warning.hidden = false;
      this.warning.textContent = t('booking.warning', { left: at >= 60 ? tn('booking.minutes.n', at / 60) : t('booking.seconds', { s: at }), ns: slot.station, at: clock(slot.end) });
      this.warning.dataset.at = String(at);
      this.warned.add(`${slot.id}:${at}`);
    } else {
      this.warning.hidden = true;
    }
  }

  async book() {
    const minutes = Number(this.minutes.value);
    const start = new Date(this.start.value).getTime() / 1000;
    if (!Number.isFinite(start) || !(minutes > 0)) { this.say(t('booking.give'), true); return; }
    try {
      const slot = { station: this.station.value, start, end: start + minutes * 60 };
      if (this.behalf.value.trim() && this.data?.role === 'admin') slot.for = this.behalf.value.trim();
      const b = await bookings('', { method: 'POST', body: slot });
      this.say(t(b.mine ? 'booking.booked' : 'booking.booked.for', { ns: b.station, from: clock(b.start), to: clock(b.end), who: b.name }));
    } catch (e) { this.say(t('booking.book.failed', { error: e.message }), true); }
    await this.refresh();
  }

  // The names "for" offers (a name two people share is offered as each one's id).
  async loadPeople() {
    this.peopleAsked = true;
    let people = [];
    try {
      people = (await api('api/people'))?.people ?? [];
    } catch { /* offered nothing: a name can still be typed */ }
    const count = new Map();
    for (const p of people) count.set(p.name, (count.get(p.name) ?? 0) + 1);
    this.people.replaceChildren(...people.map((p) => new Option(`${t(`role.${p.role}`)} · ${p.kind === 'lti' ? t('booking.from.lms') : p.kind}${count.get(p.name) > 1 ? ` · ${p.name}` : ''}`,
      count.get(p.name) > 1 ? p.id : p.name)));
  }

  async cancel(b) {
    try {
      await bookings(`/${b.id}`, { method: 'DELETE' });
      this.say(t('booking.cancelled', { ns: b.station, at: clock(b.start) }));
    } catch (e) { this.say(t('booking.cancel.failed', { error: e.message }), true); }
    await this.refresh();
  }

  async attach() {
    if (!(await this.refresh()) || this.button.hidden) return;
    setInterval(() => this.refresh(), REFRESH);
    setInterval(() => { if (this.inLine) this.pollQueue(); }, 2000);   // in line: look more often
    setInterval(() => this.tick(), 1000);
  }
}

// The page's one module mounts it (js/ide/main.js, js/teleop/main.js, js/class/main.js), as it does the recorder.
export function mountBooking(bar = document.querySelector('#bar')) {
  if (!bar) return null;
  const booking = new Booking(bar);
  booking.attach();
  return booking;
}
