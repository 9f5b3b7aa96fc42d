// The robot namespace (a fleet station such as /s07, see rosgate --fleet): robot blocks, the
// world view and the teleop page use it. It comes from ?ns= in the page's URL, else from what
// this browser remembered; "Claim a robot" asks the gateway's /fleet/claim for a free one.
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
  const input = $('#ns');
  input.value = ns;
  const set = (value) => {
    const next = normNamespace(value);
    input.value = next;
    if (next === ns) return;
    ns = next;
    saveNamespace(ns);
    history.replaceState(history.state, '', urlWithNamespace(ns));
    onChange(ns);
  };
  input.addEventListener('change', () => set(input.value));
  $('#claim').onclick = async () => {
    try {
      const r = await call(CLAIM_SERVICE, {});
      if (!r.success) throw new Error(r.message || 'no robot is free');
      if (claimed && claimed !== normNamespace(r.message)) call(`${claimed}/fleet/release`, {}).catch(() => {});
      claimed = normNamespace(r.message);
      set(claimed);
    } catch (e) { onError(`cannot claim a robot: ${e.message}`); }
  };
  return {
    get: () => ns,
    set,
    claimable: (yes) => { $('#claim').hidden = !yes; },
  };
}
