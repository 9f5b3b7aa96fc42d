// The pages' words in the reader's language. The texts live in i18n/<lang>.json (flat keys to
// strings with {name} placeholders) and the languages offered in i18n/languages.json, so a
// language or a string is added without touching code; a string missing from a language, or a
// language whose file is missing, falls back to English.
//
// The language is, in order: the page's ?lang= (an LMS launch passes its
// launch_presentation.locale this way; kept for the tab's other pages in sessionStorage), the
// choice made in the page's language menu (localStorage, and a cookie so the gateway's own
// login page follows it), the ?lang= an earlier page of this tab had, then the browser's
// navigator.languages; English when none of them is offered.
//
// This module loads its texts with a top-level await: every module that imports it runs once
// they are here, so t() is synchronous everywhere. Before that it translates the page's static
// words (data-i18n, data-i18n-title, -placeholder, -aria-label; data-i18n-js marks words a
// script writes), sets <html lang dir>, and on
// pages with Blockly loads Blockly's own messages for the language (vendor/blockly/msg/<lang>.js)
// and puts this project's ROSGATE_* strings into Blockly.Msg, which the toolbox and the block
// definitions name as %{BKY_ROSGATE_...}.

const STORE = 'rosgate.lang';          // the menu's choice (localStorage)
const TAB = 'rosgate.lang.tab';        // a ?lang= seen in this tab (sessionStorage)
export const COOKIE = 'rosgate-lang';  // read by the gateway's login page
const RTL = new Set(['ar', 'arc', 'dv', 'fa', 'he', 'ks', 'ku', 'ps', 'sd', 'ug', 'ur', 'yi']);
const base = new URL('../', import.meta.url);   // ide/

const browser = typeof document !== 'undefined';   // else Node, whose tests import page modules
const readStore = (store, key) => { try { return globalThis[store].getItem(key); } catch { return null; } };
const writeStore = (store, key, value) => { try { globalThis[store].setItem(key, value); } catch { /* private mode */ } };

// A file of texts, or null when there is none. A fetch the network or a busy gateway failed is
// tried twice more (a home link drops one now and then); a 404 is an answer, not a failure.
async function getJson(path, tries = 3) {
  try {
    if (!browser) {
      const { readFile } = await import('node:fs/promises');
      return JSON.parse(await readFile(new URL(path, base), 'utf8'));
    }
    const res = await fetch(new URL(path, base), { cache: 'no-cache' });
    if (res.ok) return await res.json();
    if (res.status < 500) return null;
    throw new Error(`${path}: HTTP ${res.status}`);
  } catch (e) {
    if (!browser || tries <= 1) {
      if (browser) console.warn(path, e);    // the developer's console: which file, and why
      return null;
    }
    await new Promise((resolve) => { setTimeout(resolve, 250); });
    return getJson(path, tries - 1);
  }
}

// The best offered language for a list of wanted tags: an exact match ('pt-br') first, else
// the tag's base language ('es-ES' -> 'es').
export function pick(wanted, offered) {
  for (const raw of wanted) {
    if (!raw) continue;
    const tag = String(raw).trim().replace('_', '-').toLowerCase();
    if (offered.includes(tag)) return tag;
    const primary = tag.split('-')[0];
    if (offered.includes(primary)) return primary;
  }
  return null;
}

const languages = (await getJson('i18n/languages.json')) ?? { en: { name: 'English' } };
const offered = Object.keys(languages);
// ?lang= names the page's language, except on a text program's page (?mode=text&lang=python),
// where an LMS's locale comes as ?locale=
const params = new URLSearchParams(globalThis.location?.search ?? '');
const fromUrl = pick([params.get('lang'), params.get('locale')], offered);
if (fromUrl) writeStore('sessionStorage', TAB, fromUrl);
export const lang = pick([fromUrl, readStore('localStorage', STORE), readStore('sessionStorage', TAB),
  ...(globalThis.navigator?.languages ?? [globalThis.navigator?.language])], offered) ?? 'en';
const [english, own] = await Promise.all([getJson('i18n/en.json'), lang === 'en' ? null : getJson(`i18n/${lang}.json`)]);
const texts = { ...(english ?? {}), ...(own ?? {}) };
export const dir = languages[lang]?.dir ?? (RTL.has(lang.split('-')[0]) ? 'rtl' : 'ltr');

// The text of `key` with its {placeholders} filled from `vars`; the key itself when no
// language has it (so a missing string shows where it is missing).
export function t(key, vars = {}) {
  const text = texts[key] ?? key;
  return text.replace(/\{(\w+)\}/g, (m, name) => (name in vars ? String(vars[name]) : m));
}

// A text given in several languages ({en: ..., es: ...}: an exercise's title, an example's words)
// in the reader's: exact, then its base language, then English, then the first given; a plain
// string is as it is.
export function localized(value) {
  if (value === null || typeof value !== 'object') return value ?? '';
  const found = pick([lang], Object.keys(value));
  return value[found ?? 'en'] ?? Object.values(value)[0] ?? '';
}

// A text that depends on a count: key.one, key.other ... chosen by the language's plural rules.
export function tn(key, n, vars = {}) {
  const form = new Intl.PluralRules(lang).select(n);
  const found = `${key}.${form}` in texts ? `${key}.${form}` : `${key}.other`;
  return t(found, { n: num(n), ...vars });
}

// Numbers and times in the reader's locale.
const numberFormats = new Map();
export function num(value, digits = null) {
  if (!Number.isFinite(value)) return '–';
  const k = digits ?? 'any';
  if (!numberFormats.has(k)) {
    numberFormats.set(k, new Intl.NumberFormat(lang, digits === null ? {} : { minimumFractionDigits: digits, maximumFractionDigits: digits }));
  }
  return numberFormats.get(k).format(value);
}
export const time = (date, options = { hour: '2-digit', minute: '2-digit', second: '2-digit' }) => new Date(date).toLocaleTimeString(lang, options);
export const day = (date, options = { weekday: 'short', day: 'numeric', month: 'short' }) => new Date(date).toLocaleDateString(lang, options);

const ATTRS = ['title', 'placeholder', 'aria-label'];
// The static words under `root`: an element's text by data-i18n, its attributes by data-i18n-<attr>
// (and inside <template>s, whose copies the scripts make later).
export function translate(root = document) {
  for (const tpl of root.querySelectorAll('template')) translate(tpl.content);
  for (const el of root.querySelectorAll('[data-i18n]')) el.textContent = t(el.dataset.i18n);
  for (const attr of ATTRS) {
    for (const el of root.querySelectorAll(`[data-i18n-${attr}]`)) el.setAttribute(attr, t(el.getAttribute(`data-i18n-${attr}`)));
  }
}

// Choosing a language: remembered, and the page opens again in it (Blockly takes its messages
// once, when it starts).
export function choose(code) {
  writeStore('localStorage', STORE, code);
  writeStore('sessionStorage', TAB, code);
  document.cookie = `${COOKIE}=${encodeURIComponent(code)}; path=/; max-age=31536000; SameSite=Lax`;
  const url = new URL(location.href);
  if (pick([url.searchParams.get('lang')], offered)) url.searchParams.delete('lang');   // not a program's ?lang=python
  url.searchParams.delete('locale');
  location.replace(url);
}

// The language menu, at the end of the page's #bar.
function addMenu() {
  const bar = document.querySelector('#bar');
  if (!bar || document.querySelector('#lang')) return;
  const menu = document.createElement('select');
  menu.id = 'lang';
  menu.className = 'lang';
  menu.setAttribute('aria-label', t('lang.menu'));
  menu.title = t('lang.menu');
  for (const [code, info] of Object.entries(languages)) {
    const option = new Option(info.name ?? code, code, code === lang, code === lang);
    option.lang = code;
    menu.append(option);
  }
  menu.addEventListener('change', () => choose(menu.value));
  bar.append(menu);
}

// Blockly's own messages (a classic script that fills Blockly.Msg), then this project's.
function loadScript(src) {
  return new Promise((resolve) => {
    const s = document.createElement('script');
    s.src = src;
    s.onload = () => resolve(true);
    s.onerror = () => resolve(false);   // Blockly has no messages for it: its English stays
    document.head.append(s);
  });
}

if (globalThis.Blockly?.Msg) {
  const file = languages[lang]?.blockly ?? lang;
  if (lang !== 'en') await loadScript(new URL(`vendor/blockly/msg/${file}.js`, base).href);
  for (const [key, value] of Object.entries(texts)) if (key.startsWith('ROSGATE_')) globalThis.Blockly.Msg[key] = value;
}

if (browser) {
  document.documentElement.lang = lang;
  document.documentElement.dir = dir;
  translate();
  addMenu();
}
