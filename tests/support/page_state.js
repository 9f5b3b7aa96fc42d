// How the tests see a page's live state, as names on `window` the pages themselves do not set
// (tests/ide/test_modules.py: no page global). Each page's entry exports its state; a module
// imported again by the same URL is the same instance, so once the page's entry has run, each name
// reads that module's export. This table is the one place that says how tests see a page.
// Installed by tests/support/page_state.py: an init script of every Chromium context
// (tests/support/fixtures.py), and with each evaluation in WebKitGTK and Firefox (engines.py).
// One expression, run as often as wanted (the second time does nothing).
(() => {
  if (Object.prototype.hasOwnProperty.call(window, '__pageState')) return;
  const ENTRIES = {   // the page's module script -> the names of its state: name -> (module) => value
    'js/ide/main.js': { rosgateIde: (m) => m.ide, rosgateRecorder: (m) => m.ide.recorder, rosgateBooking: (m) => m.ide.booking },
    'js/teleop/main.js': { teleop: (m) => m.teleop, rosgateRecorder: (m) => m.teleop.recorder, rosgateBooking: (m) => m.teleop.booking },
    'js/class/main.js': { classView: (m) => m.view, rosgateBooking: (m) => m.view.booking },
    'js/twin/main.js': { twin: (m) => m.twin },
    'js/inspect/main.js': { inspect: (m) => m.inspect },
  };
  const state = { module: null, names: null, asked: false };
  Object.defineProperty(window, '__pageState', { value: state });
  // the page's entry, once its module script is in the document: imported (its own instance)
  const load = () => {
    if (state.asked) return;
    const script = document.querySelector('script[type="module"][src]');
    if (!script) return;
    const entry = Object.keys(ENTRIES).find((e) => new URL(script.src).pathname.endsWith(`/${e}`));
    if (!entry) return;
    state.asked = true;
    state.names = ENTRIES[entry];
    import(script.src).then((m) => { state.module = m; }, () => { state.asked = false; });
  };
  const names = new Set(Object.values(ENTRIES).flatMap((e) => Object.keys(e)));
  for (const name of names) {
    Object.defineProperty(window, name, {
      configurable: true,
      get() {
        load();
        const read = state.names?.[name];
        return state.module && read ? read(state.module) : undefined;
      },
    });
  }
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', load);
  else load();
})()
