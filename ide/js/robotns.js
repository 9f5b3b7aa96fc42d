// The robot namespace (a fleet station such as /s07, see rosgate --fleet): robot blocks, the
// world view and the teleop page use it. It comes from ?ns= in the page's URL, else from what
// this browser remembered; "Claim a robot" asks the gateway's /fleet/claim for a free one, and
// on a fleet a page with no namespace claims one by itself. Under the driver lease
// (--exclusive-control) the page takes its station's lease and says so when another holds it.
import { normNamespace } from '../runtime/util.js';

export const CLAIM_SERVICE = '/fleet/claim';
const KEY = 'rosgate.ns';

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

// The page's URL with ?ns= replaced (or left out when it was not there and ns is the stored one).
export function urlWithNamespace(ns, href = location.href) {
  const url = new URL(href);
  if (url.searchParams.has('ns') || ns) url.searchParams.set('ns', ns);
  url.search = url.searchParams.toString().replace(/%2F/gi, '/');    // ?ns=/s07 stays readable
  return url.toString();
}

/**
 * Binds the namespace field and the "Claim a robot" button (#ns, #claim).
 * call(service, args) -> Promise of the response values; onChange(ns) runs on every change.
 * Returns {get(), set(ns), claimable(bool)}.
 */
export function bindNamespace({ call, onChange, onError = () => {}, $ = (s) => document.querySelector(s) }) {
  let ns = loadNamespace();
  let claimed = '';           // the station this page claimed, given back when it claims another
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
  input.addEventListener('change', () => set(input.value));
  const claim = async () => {
    try {
      const r = await call(CLAIM_SERVICE, {});
      if (!r.success) throw new Error(r.message || 'no robot is free');
      if (claimed && claimed !== normNamespace(r.message)) call(`${claimed}/fleet/release`, {}).catch(() => {});
      claimed = normNamespace(r.message);
      set(claimed);
    } catch (e) { onError(`cannot claim a robot: ${e.message}`); }
  };
  $('#claim').onclick = claim;
  let fleet = false;
  let autoClaimed = false;
  const self = {
    get: () => ns,
    set,
    claim,
    get fleet() { return fleet; },
    // The gateway runs a fleet: show Claim, and claim a station when this page has none.
    claimable: (yes) => {
      fleet = yes;
      $('#claim').hidden = !yes;
      if (yes && !ns && !autoClaimed) { autoClaimed = true; claim(); }
    },
    // Follows the driver lease: its namespace, a free station taken, another's station named.
    follow: (lease) => {
      followers.push((next) => lease.setNamespace(next));
      followLease(self, lease, { onError, $ });
    },
  };
  return self;
}

function followLease(robotNs, lease, { onError, $ }) {
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
      return `${st}|${d ? (d.client === lease.me ? 'you' : `held by ${d.name}`) : 'free'}`;
    }).join(',');
    if (list.dataset.labels !== labels) {
      list.dataset.labels = labels;
      list.replaceChildren(...labels.split(',').filter(Boolean).map((x) => {
        const [value, label] = x.split('|');
        return new Option(label, value);
      }));
    }
    const ns = robotNs.get();
    if (!ns || lease.group === '/') return;
    // once per connection and station: take it when free, say who holds it when not
    if (lease.state === 'nobody' && !(taken.ros === lease.ros && taken.ns === ns)) {
      taken = { ros: lease.ros, ns };
      lease.take();
    }
    const warn = lease.state === 'other' ? `${ns} ${lease.driver.client}` : '';
    if (warn && warn !== warned) {
      onError(`${ns} is driven by ${lease.label}: pick a free robot${robotNs.fleet ? ' or press "Claim a robot"' : ''}`);
    }
    warned = warn;
  });
}
