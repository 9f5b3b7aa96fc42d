// The robot namespace (a station such as /s07): robot blocks, the world view and the teleop page
// use it. On a gateway with stations (rosgate --fleet N, or robots in their own namespaces) the
// gateway says which one is yours: a station belongs to a person (the signed-in name, else this
// browser's id, kept here and sent with every request as a cookie), so a reload, a closed tab or a
// sleeping tablet comes back to the same one, and a page never lands on another person's.
// ?ns=/s07 in the address asks for that station; "Claim a robot" asks for any free one; when none
// is free the page says so and drives nothing. Without stations the namespace comes from ?ns= or
// what this browser remembered. Under the driver lease (--exclusive-control) the page takes its
// own station's lease when it is free, never after the teacher's Stop (only Take resumes), and
// says who holds a station that is not its own. After the teacher's Release the page drives
// nothing and says so (its banner) until this person claims a station again: her other pages
// left open had taken the released station back on their next command.
import { normNamespace } from '../../runtime/util.js';
import { t } from '../i18n.js';

export const CLAIM_SERVICE = '/fleet/claim';
export const STATIONS_TOPIC = '/rosgate/stations';
const KEY = 'rosgate.ns';
const BROWSER_KEY = 'rosgate.browser';
const BROWSER_COOKIE = 'rosgate_browser';
const BROWSER_ID = /^[A-Za-z0-9_-]{8,64}$/;
export const STOPPED = t('page.stopped');

export function loadNamespace(search = location.search) {
  const fromUrl = new URLSearchParams(search).get('ns');
  if (fromUrl !== null) {
    saveNamespace(fromUrl);
    return normNamespace(fromUrl);
  }
  try { return normNamespace(localStorage.getItem(KEY)); } catch { return ''; }
}

export function saveNamespace(ns) {
  try { localStorage.setItem(KEY, normNamespace(ns)); } catch { /* storage off */ }
}

// This browser's id (random, kept in localStorage), also set as a cookie so that the websocket
// and the HTTP API know the browser: without --auth the gateway keeps a station for it.
export function browserId() {
  let id = '';
  try { id = localStorage.getItem(BROWSER_KEY) ?? ''; } catch { /* storage off */ }
  if (!BROWSER_ID.test(id)) {
    id = Array.from(crypto.getRandomValues(new Uint8Array(16)), (b) => b.toString(16).padStart(2, '0')).join('');
    try { localStorage.setItem(BROWSER_KEY, id); } catch { /* storage off: this page's id only */ }
  }
  document.cookie = `${BROWSER_COOKIE}=${id}; path=/; max-age=31536000; SameSite=Strict`;
  return id;
}

// The page's URL with ?ns= replaced (or left out when it was not there and ns is the stored one).
export function urlWithNamespace(ns, href = location.href) {
  const url = new URL(href);
  if (url.searchParams.has('ns') || ns) url.searchParams.set('ns', ns);
  url.search = url.searchParams.toString().replace(/%2F/gi, '/');    // ?ns=/s07 stays readable
  return url.toString();
}

/**
 * Binds the namespace field and the "Claim a robot" button (#ns, #claim).
 * call(service, args) -> Promise of the response values; onChange(ns) runs on every change;
 * onError(text) tells the person (console or notice).
 * Returns {get(), set(ns), claim(), claimable(bool), attach(ros), follow(lease), whyNot(), mine, fleet}.
 */
export function bindNamespace({ call, onChange, onError = () => {}, onState = () => {}, $ = (s) => document.querySelector(s) }) {
  browserId();
  const asked = normNamespace(new URLSearchParams(location.search).get('ns'));   // a station asked for
  let ns = loadNamespace();
  let fleet = false;          // the gateway hands out stations
  let known = false;          // ... and this page knows whether it does
  let mine = '';              // the station the gateway says is this person's
  let none = '';              // why this person has no station ('' : not known to be so)
  let released = '';          // the teacher released this person's station: what the page says until a claim
  let lease = null;
  let ros = null;
  const followers = [];
  const input = $('#ns');
  input.value = ns;
  const set = (value) => {
    const next = normNamespace(value);
    input.value = next;
    if (next === ns) return;
    ns = next;
    saveNamespace(ns);
    history.replaceState(history.state, '', urlWithNamespace(ns));
    for (const f of followers) f(ns);
    onChange(ns);
  };
  // Asks the gateway for this person's station (target: that one, if nobody else has it).
  const claim = async (target = '') => {
    let r;
    try {
      r = await call(target ? `${target}/fleet/claim` : CLAIM_SERVICE, {});
    } catch (e) { onError(t('claim.failed', { error: e.message })); return; }
    if (r.success) {
      mine = normNamespace(r.message);
      none = '';
      released = '';
      set(mine);
      for (const f of followers) f(ns);
      onState();
      return;
    }
    if (target) {             // another person's: this page may watch it, not drive it
      set(target);
      onError(t('claim.watch', { why: r.message || t('claim.not.free', { ns: target }) }));
      return;
    }
    mine = '';
    none = r.message || t('claim.none.free');
    set('');
    onError(t('claim.no.robot.long', { why: none }));
    onState();
  };
  input.addEventListener('change', () => (fleet ? claim(normNamespace(input.value)) : set(input.value)));
  $('#claim').onclick = () => claim();
  // what the gateway says about stations: a station of this person released by the teacher
  // (it holds like the teacher's Stop: no page of hers drives it until she claims a robot again)
  const onStations = (info) => {
    if (!mine || info.owners?.[mine]) return;
    const by = info.released?.[mine]?.by;
    released = t(by ? 'claim.released.by' : 'claim.released', { by, ns: mine });
    onError(released);
    mine = '';
    for (const f of followers) f(ns);
    onState();
  };
  const self = {
    get: () => ns,
    set,
    claim,
    get fleet() { return fleet; },
    get mine() { return mine; },
    // Why this page drives nothing at all until a claim ('' : it may): released, or no robot.
    get lost() { return fleet && !mine ? (released || (none ? t('claim.no.robot', { why: none }) : '')) : ''; },
    // The gateway hands out stations: show Claim, and ask for this person's station once
    // (returns that claim, for a page that waits for its answer).
    claimable: (yes) => {
      const first = !known;
      known = true;
      fleet = yes;
      $('#claim').hidden = !yes;
      return yes && first ? claim(asked) : Promise.resolve();
    },
    // A new connection: follow the gateway's announcement of who owns which station.
    attach: (next) => {
      ros = next;
      ros.on(STATIONS_TOPIC, (m) => {
        if (ros !== next) return;
        try { onStations(JSON.parse(m.msg.data)); } catch { /* not ours */ }
      });
      ros.callOnConnection({ op: 'subscribe', id: `subscribe:${STATIONS_TOPIC}:ns`, topic: STATIONS_TOPIC, type: 'std_msgs/msg/String' });
    },
    // What the page's banner says while it holds (the IDE and the teleop page say the same):
    // released, no robot, or the teacher's stop until Take ('' : nothing holds this robot).
    banner: () => self.lost || (lease?.halted && lease.state !== 'you' ? STOPPED : ''),
    // Why this page may not drive now ('' : it may): no robot of its own, another's, stopped.
    whyNot: () => {
      if (fleet && released && !mine) return released;
      if (fleet && !ns) return none ? t('claim.no.robot', { why: none }) : t('claim.not.yet');
      if (lease?.halted && lease.state !== 'you') {
        return t('claim.teacher.stopped', { ns: ns || t('ide.this.robot') });
      }
      if (fleet && ns !== mine && lease?.state === 'other') return t('claim.driven.by', { ns, who: lease.label });
      return '';
    },
    // Follows the driver lease: its namespace, its own free station taken, another's named.
    follow: (l) => {
      lease = l;
      followers.push((next) => { l.ownStation = Boolean(mine) && next === mine; l.setNamespace(next); });
      followLease(self, l, { onError, $, ready: () => known });
    },
  };
  return self;
}

function followLease(robotNs, lease, { onError, $, ready }) {
  let taken = {};
  let warned = '';
  const list = document.createElement('datalist');
  list.id = 'ns-stations';
  document.body.append(list);
  $('#ns').setAttribute('list', list.id);
  lease.setNamespace(robotNs.get());
  lease.addEventListener('change', () => {
    if (lease.ns !== robotNs.get()) lease.setNamespace(robotNs.get());
    const stations = lease.info?.stations ?? [];
    const labels = stations.map((st) => {
      const d = lease.holderOf(st);
      return `${st}|${d ? (d.client === lease.me ? t('driver.you') : t('station.held.by', { who: d.name })) : t('station.free')}`;
    }).join(',');
    if (list.dataset.labels !== labels) {
      list.dataset.labels = labels;
      list.replaceChildren(...labels.split(',').filter(Boolean).map((x) => {
        const [value, label] = x.split('|');
        return new Option(label, value);
      }));
    }
    const ns = robotNs.get();
    if (!ns || lease.group === '/' || !ready()) return;
    // once per connection and station: take this person's own station when it is free and not
    // stopped (the gateway checks the same: "take-if-free")
    const own = robotNs.fleet ? ns === robotNs.mine : true;
    if (own && lease.state === 'nobody' && !lease.halted && !(taken.ros === lease.ros && taken.ns === ns)) {
      taken = { ros: lease.ros, ns };
      lease.command(`take-if-free ${lease.group}`);
    }
    const warn = lease.state === 'other' ? `${ns} ${lease.driver.client}` : '';
    if (warn && warn !== warned) {
      onError(t(robotNs.fleet ? 'claim.driven.pick.claim' : 'claim.driven.pick', { ns, who: lease.label }));
    }
    warned = warn;
  });
}
