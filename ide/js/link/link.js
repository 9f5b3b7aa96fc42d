// The pages' link to the gateway (the IDE, the teleop page, the class view): one connection at a
// time, seen and made again by itself.
//
// Seen: every PING_EVERY the page sends rosgate's `ping` op (docs/protocol.md); the `pong` gives
// the round trip, and any frame from the gateway proves the link alive. A link that carries
// nothing for one ping's interval and its retransmission timeout (TCP's, RFC 6298: SRTT + 4·RTTVAR,
// never under 1 s, up to SILENCE_CAP: SILENCE where round trips are quick and steady, longer where
// a busy gateway's are slow and uneven), is lost (a TCP connection through an outage stays "open"
// for minutes). Measured on a loaded 2-core machine with Pyodide starting in three pages: pongs
// 0.87-1.0 s apart with no outage, so 0.8 s dropped working links and stopped their programs.
// The page says so within 1.5 s and drops the connection — what it queued is stale, and the
// gateway stops the robot by itself when commands stop coming (its cmd timeout). A server that
// does not know `ping` answers it with an error status: the page then relies on the socket alone.
//
// Made again: one attempt at a time. One refused or closed (a gateway restarting) is followed by
// the next after a backoff with jitter (so thirty pages do not knock at once), capped at
// RETRY.cap; one that goes unanswered (its SYN lost in an outage, retried by the kernel only
// seconds later) is dropped after attemptTimeout() and a fresh one sent at once, so the link's
// return is met within about 1.5 s. The page's station is the person's (robotns.js), so it is kept.
import { Ros } from 'roslib';
import { t, num } from '../i18n.js';

export const PING_EVERY = 250;          // ms between pings
const RTO_MIN = 1000;                   // ms: RFC 6298 (2.4) rounds a shorter timeout up to 1 s
export const SILENCE = PING_EVERY + RTO_MIN;   // ms without a frame from the gateway: the link is lost
const SILENCE_CAP = 5000;               // ms: the longest a slow gateway's own round trips may stretch it
const LOOK_EVERY = 100;                 // ms between looks at the silence
export const RETRY = { first: 150, factor: 2, cap: 800, jitter: 0.3 };   // ms; each delay ±30 %
export const ATTEMPT_TIMEOUT = 2500;    // ms an attempt may go unanswered while the round trip is unknown
const PING_ID = 'link.ping';
const links = new Set();                // the page's links: a heavy moment of the page makes each patient

// A heavy moment of the page (a Python worker starting: Pyodide compiling): every link of the page
// allows the longer silence until `promise` settles (Link.patient). Returns `promise`.
export function heavy(promise) {
  for (const link of links) link.patient(promise);
  return promise;
}

// The delay before attempt n (0, 1, ...): first·factor^n, at most cap, spread by ±jitter.
export function backoff(n, { first, factor, cap, jitter } = RETRY, random = Math.random) {
  return Math.min(cap, first * factor ** n) * (1 - jitter + 2 * jitter * random());
}

// url: the websocket address (a string, or a function giving it at each attempt).
// Events: 'open' (detail: the new Ros; subscribe and advertise again there), 'lost' (detail:
// 'silent' or 'closed'; the old Ros is dropped), 'state' (after each change; see .state).
export class Link extends EventTarget {
  constructor(url) {
    super();
    this.url = typeof url === 'function' ? url : () => url;
    this.ros = null;
    this.state = 'idle';       // connecting | connected | lost
    this.rtt = null;           // ms, the last pong's round trip
    this.srtt = null;          // ms, its smoothed mean and mean deviation (RFC 6298)
    this.rttvar = 0;
    this.heardAt = null;       // performance.now() of the last frame from the gateway
    this.dataAt = null;        // ... of the last frame that was not a pong
    this.currentAt = null;     // ... when the page sent the ping whose pong came last: all the gateway
                               // had for the page by then has arrived (one queue, in order)
    this.pings = true;         // the server answers pings (rosgate does)
    this.pongs = 0;
    this.tries = 0;
    this.pending = new Set();  // attempts not yet open
    this.retry = null;
    this.ticker = null;
    this.pinged = 0;
    this.busy = 0;             // heavy moments of the page under way (patient())
    links.add(this);
  }

  // A heavy moment the page knows of: Pyodide compiling its 10 MB of WebAssembly takes both cores of
  // a 2-core machine for seconds, and the gateway's pongs come late then while the page's own timers
  // may still run on time (measured on a loaded 2-core machine: pongs 0.5-0.7 s late, three links of
  // four declared silent at 0.8 s). Until `promise` settles the link allows SILENCE_CAP of silence:
  // an outage then shows within 5 s instead of 1.25 s (the gateway stops the robot by itself).
  patient(promise) {
    this.busy += 1;
    const done = () => { this.busy -= 1; };
    Promise.resolve(promise).then(done, done);
    return promise;
  }

  // The page's clock for stamps ("t" on publish, ms): never jumps while the page lives.
  now() { return performance.now(); }

  start() {
    this.tries = 0;
    this._attempt();
  }

  // Drop the connection and connect again at once (a new address, the ↻ button).
  restart() {
    this._drop();
    for (const ros of this.pending) this._abandon(ros);
    this._set('connecting');
    this.start();
  }

  // A short line for the page: round trip and how old the newest data is.
  describe(now = performance.now()) {
    if (this.state !== 'connected') return '';
    const parts = [];
    if (this.rtt !== null) parts.push(t('link.rtt', { ms: Math.round(this.rtt) }));
    const age = this.age(now);
    if (age !== null) parts.push(t('link.age', { s: num(age / 1000, 1) }));
    return parts.join(' · ');
  }

  // How old (ms) what the page shows may be: since its newest message, or since the ping of its
  // newest pong, whichever is later. The gateway sends a client's messages and replies in one
  // queue, in order, so a pong says the page has everything sent before it: a robot that is idle
  // (turtlesim's markers change only when the turtle moves) shows current data, not an age that
  // grows; a link that lags makes the pongs late and the age grow. null: nothing received yet.
  age(now = performance.now()) {
    if (this.dataAt === null) return null;
    return now - Math.max(this.dataAt, this.currentAt ?? -Infinity);
  }

  _set(state) {
    this.state = state;
    this.dispatchEvent(new CustomEvent('state', { detail: state }));
  }

  // One attempt at a time (browsers open one websocket to a host at a time anyway, RFC 6455 4.1).
  _attempt() {
    clearTimeout(this.retry);
    if (this.state === 'idle') this._set('connecting');
    const ros = new Ros({});
    this.pending.add(ros);
    const failed = () => {   // refused or closed before it opened: the server is there, or soon
      if (!this.pending.delete(ros)) return;
      clearTimeout(timeout);
      this._later(backoff(this.tries++));
    };
    const timeout = setTimeout(() => {   // no answer: the network is dark; try afresh at once
      this._abandon(ros);
      this._later(0);
    }, this.attemptTimeout());
    ros.on('connection', () => {
      clearTimeout(timeout);
      if (!this.pending.delete(ros) || this.ros) { ros.close(); return; }
      this._open(ros);
    });
    ros.on('close', () => {
      if (ros === this.ros) this._lose('closed');
      else failed();
    });
    ros.on('error', () => {});   // a close follows
    ros.connect(this.url())
      .then(() => ros.transport?.on('message', (m) => this._heard(ros, m)))
      .catch(failed);
  }

  // How long an attempt may go unanswered. The kernel sends a connection's SYN again after 1 s,
  // then after 3 s more: an attempt whose SYNs fell into an outage is dropped soon after the
  // first retry and a fresh one sent, so the link's return is met within about 1.5 s. A slow link
  // (its round trip known from the pongs) gets the time its handshake needs.
  attemptTimeout() {
    if (this.rtt === null) return ATTEMPT_TIMEOUT;
    return Math.min(4000, Math.max(1200, 2 * this.rtt + 600));
  }

  _later(ms) {
    clearTimeout(this.retry);
    this.retry = setTimeout(() => { if (!this.ros && !this.pending.size) this._attempt(); }, ms);
  }

  _abandon(ros) {
    if (!this.pending.delete(ros)) return;
    ros.removeAllListeners?.();
    try { ros.close(); } catch { /* never opened */ }
  }

  _open(ros) {
    clearTimeout(this.retry);
    this.ros = ros;
    this.tries = 0;
    this.heardAt = performance.now();
    this.dataAt = null;
    this.currentAt = null;
    this.rtt = null;
    this.pongs = 0;
    this.pings = true;
    this._set('connected');
    this.dispatchEvent(new CustomEvent('open', { detail: ros }));
    this._ping();
    this.pinged = performance.now();
    this.ticked = this.pinged;
    this.ticker = setInterval(() => this._tick(), LOOK_EVERY);
  }

  _ping() {
    if (this.pings) this.ros?.callOnConnection({ op: 'ping', id: PING_ID, t: this.now() });
  }

  _tick() {
    if (!this.ros) return;
    const now = performance.now();
    // a page that was busy itself (its timer came late: a long task, a loaded tablet) heard
    // nothing in that time through no fault of the link: the stall does not count as silence
    const stalled = now - this.ticked - LOOK_EVERY;
    if (stalled > LOOK_EVERY) this.heardAt += stalled;
    this.ticked = now;
    // silence counts only where pings are answered (elsewhere a quiet link may be well), and not
    // in a hidden tab, whose timers the browser slows to one a second or less
    const hidden = typeof document !== 'undefined' && document.hidden;
    if (this.pongs && !hidden && now - this.heardAt > this.silence()) { this._lose('silent'); return; }
    if (now - this.pinged >= PING_EVERY - LOOK_EVERY / 2) { this.pinged = now; this._ping(); }
  }

  _measured(rtt) {
    this.rtt = rtt;
    if (this.srtt === null) {
      this.srtt = rtt;
      this.rttvar = rtt / 2;
    } else {
      this.rttvar = 0.75 * this.rttvar + 0.25 * Math.abs(this.srtt - rtt);
      this.srtt = 0.875 * this.srtt + 0.125 * rtt;
    }
  }

  // How long the link may carry nothing before it counts as lost.
  silence() {
    if (this.busy) return SILENCE_CAP;
    if (this.srtt === null) return SILENCE;
    return Math.min(SILENCE_CAP, PING_EVERY + Math.max(RTO_MIN, this.srtt + 4 * this.rttvar));
  }

  _heard(ros, m) {
    if (ros !== this.ros) return;
    const now = performance.now();
    this.heardAt = now;
    if (m?.op === 'pong') {
      this.pongs += 1;
      if (typeof m.t === 'number') {
        this._measured(now - m.t);
        this.currentAt = Math.max(this.currentAt ?? -Infinity, Math.min(m.t, now));
      }
    } else if (m?.op === 'status' && m.id === PING_ID) {
      // not rosgate ("Unknown operation"): no pings, no silence detection; another refusal
      // (not signed in yet) leaves them on
      if (/unknown op/i.test(m.msg ?? '')) this.pings = false;
    } else {
      this.dataAt = now;
    }
  }

  _drop() {
    clearInterval(this.ticker);
    this.ticker = null;
    const old = this.ros;
    this.ros = null;
    if (old) {
      old.removeAllListeners?.();
      try { old.close(); } catch { /* already closed */ }
    }
    return old;
  }

  _lose(why) {
    // what the page knew when it gave the link up (shown by tests and the console's diagnostics)
    const now = performance.now();
    this.lastLost = { why, silent: Math.round(now - this.heardAt), allowed: this.silence(), busy: this.busy,
      srtt: this.srtt, rttvar: this.rttvar, pongs: this.pongs };
    const old = this._drop();
    if (!old) return;
    this._set('lost');
    this.dispatchEvent(new CustomEvent('lost', { detail: why }));
    this.tries = 0;
    this._attempt();
  }
}
