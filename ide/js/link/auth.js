// Who is signed in, from the gateway's /whoami: {auth, name, role}. Without --auth everyone is
// an admin; with it, no token means "not signed in" (the page links to /login and does not
// connect) and the role decides what the page offers.
import { t } from '../i18n.js';
import { api, ApiError } from './api.js';

// What each role may do in the IDE (the gateway enforces the same; this only hides what would fail).
export const ABILITIES = {
  viewer: { run: false, save: false },
  operator: { run: true, save: true },
  admin: { run: true, save: true, everyone: true },
};

// {auth, signedIn, name, role, reason}
export async function whoami() {
  let me;
  try {
    me = await api('whoami');
  } catch (e) {
    if (e instanceof ApiError && (e.status === 401 || e.status === 429)) {
      return { auth: true, signedIn: false, name: null, role: null, reason: e.body?.error ?? '' };
    }
    // no answer: let the socket tell; another error: a gateway without /whoami
    return { auth: false, signedIn: true, name: null, role: 'admin' };
  }
  me ??= {};
  return { auth: !!me.auth, signedIn: true, name: me.name ?? null, role: me.role ?? 'viewer' };
}

export function abilities(me) {
  return me.signedIn ? (ABILITIES[me.role] ?? ABILITIES.viewer) : { run: false, save: false };
}

// The sign-in link comes back to this page (with its query: a share link keeps its program).
export function loginHref(loc = location) {
  return `login?next=${encodeURIComponent(loc.pathname + loc.search + loc.hash)}`;
}

// Shows who is signed in (or the sign-in link) and disables what the role may not use.
// `controls`: {run: [elements], save: [elements]}.
export function showIdentity(me, { signin, who, whoName, whoRole }, controls) {
  signin.hidden = me.signedIn;
  signin.href = loginHref();
  who.hidden = !(me.auth && me.signedIn);
  whoName.textContent = me.name ?? '';
  whoRole.textContent = me.role ? `(${t(`role.${me.role}`)})` : '';
  const can = abilities(me);
  const why = me.signedIn ? t('auth.role.may.not', { role: t(`role.${me.role}`) }) : t('auth.signin.first');
  for (const [what, elements] of Object.entries(controls)) {
    for (const el of elements) {
      if (!el) continue;
      el.disabled = !can[what];
      if (!can[what]) el.title = why;
    }
  }
  document.body.dataset.role = me.signedIn ? me.role : 'none';
}
