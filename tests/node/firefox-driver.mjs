// Firefox ESR driven by puppeteer-core over WebDriver BiDi, for the pages' smoke suite in three
// engines (tests/support/engines.py): Debian has no geckodriver, and Firefox speaks BiDi itself.
// One command per stdin line, one answer per stdout line (JSON):
//   {"op": "open", "url": U, "width": W, "height": H}   a new tab at U (the previous one closed)
//   {"op": "js", "expr": E}                              the value of the expression E in the page
//   {"op": "click" | "fill", "selector": S, "text": T}
//   {"op": "key", "key": "ArrowUp", "down": true}
//   {"op": "touch", "phase": "start" | "move" | "end", "x": X, "y": Y}
//   {"op": "problems"}                                   the page's console errors, uncaught errors,
//                                                        failed requests and HTTP errors since it opened
//   {"op": "quit"}
// The first line out is {"ready": true, "version": ...} once the browser runs. Nothing is
// downloaded: the browser is FIREFOX (default /usr/bin/firefox-esr).
import { createInterface } from 'node:readline';
import puppeteer from 'puppeteer-core';

const out = (obj) => process.stdout.write(`${JSON.stringify(obj)}\n`);
const browser = await puppeteer.launch({
  browser: 'firefox',
  executablePath: process.env.FIREFOX || '/usr/bin/firefox-esr',
  headless: true,
  // no first-run pages, no updates, no telemetry: the profile is a fresh one per launch
  extraPrefsFirefox: { 'browser.shell.checkDefaultBrowser': false, 'app.update.enabled': false,
    'datareporting.policy.dataSubmissionEnabled': false, 'toolkit.telemetry.enabled': false },
});
let page = null;
let problems = [];

const ops = {
  async open({ url, width = 1280, height = 860 }) {
    if (page) await page.close();
    page = await browser.newPage();
    const seen = problems = [];
    page.on('console', (m) => { if (m.type() === 'error') seen.push(`console: ${m.text()}`); });
    page.on('pageerror', (e) => seen.push(`error: ${e.message ?? e}`));
    page.on('requestfailed', (r) => seen.push(`failed: ${r.url()} ${r.failure()?.errorText ?? ''}`));
    page.on('response', (r) => { if (r.status() >= 400) seen.push(`${r.status()}: ${r.url()}`); });
    await page.setViewport({ width, height, hasTouch: true });
    await page.goto(url, { waitUntil: 'load' });
  },
  js: ({ expr }) => page.evaluate(expr),
  problems: () => [...problems],
  click: ({ selector }) => page.click(selector),
  async fill({ selector, text }) {
    await page.$eval(selector, (el) => { el.value = ''; el.focus(); });
    await page.keyboard.type(text);
  },
  key: ({ key, down }) => (down ? page.keyboard.down(key) : page.keyboard.up(key)),
  touch({ phase, x, y }) {
    if (phase === 'start') return page.touchscreen.touchStart(x, y);
    if (phase === 'move') return page.touchscreen.touchMove(x, y);
    return page.touchscreen.touchEnd();
  },
};

out({ ready: true, version: await browser.version() });
for await (const line of createInterface({ input: process.stdin })) {
  if (!line.trim()) continue;
  const cmd = JSON.parse(line);
  if (cmd.op === 'quit') break;
  try {
    const value = await ops[cmd.op](cmd);
    out({ ok: true, value: value === undefined ? null : value });
  } catch (e) {
    out({ ok: false, error: String(e?.message ?? e) });
  }
}
await browser.close();
process.exit(0);   // stdin's reader would keep the process
