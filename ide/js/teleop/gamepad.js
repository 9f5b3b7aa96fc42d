// Gamepads on the teleop page (the browser's Gamepad API, the "standard" mapping every common pad
// has): the left stick drives (up: forward; left: turn left) while the dead-man button, the left
// shoulder button (LB / L1, button 4, as teleop_twist_joy's enable_button), is held. Releasing it,
// the stick back in its dead zone, the pad unplugged or the tab hidden is a released joystick:
// the page sends its zero and stops. After an unplug, a hidden tab or a lost connection the pad
// drives again only once the dead-man button has been let go and pressed anew (so it does at first
// too), so a pad left lying with its button held (a book on it) does not start the robot when the
// tab comes back or the page reloads.
//
// The browser gives no events for a stick: the pad is read each animation frame while one is
// connected (frames stop in a hidden tab, which stops the robot anyway).

export const DEADMAN = 4;          // standard mapping: the left shoulder button (LB, L1)
export const AXIS_TURN = 0;        // left stick, right: +1
export const AXIS_DRIVE = 1;       // left stick, down: +1
export const DEAD_ZONE = 0.12;     // a stick at rest rarely reads exactly 0

const idle = () => ({ x: 0, y: 0, active: false });

// The pad's command: {x (right +), y (forward +), active}; a stick inside the dead zone is 0.
export function readPad(pad) {
  if (!pad?.connected) return { ...idle(), held: false };
  const held = Boolean(pad.buttons[DEADMAN]?.pressed);
  const axis = (i) => { const v = pad.axes[i] ?? 0; return Math.abs(v) < DEAD_ZONE ? 0 : Math.max(-1, Math.min(1, v)); };
  const x = axis(AXIS_TURN), y = -axis(AXIS_DRIVE);
  return { x, y, active: held && (x !== 0 || y !== 0), held };
}

/**
 * Follows the first connected gamepad. onInput({x, y, active}) on every change; onPad(name or '')
 * when one is connected or gone. stop() is a release from outside (a hidden tab, a lost link):
 * the pad is disarmed until its dead-man button is let go.
 */
export function watchGamepads({ onInput, onPad = () => {} }) {
  const get = () => (navigator.getGamepads?.() ?? []).find((p) => p?.connected) ?? null;
  let last = idle();
  let armed = false;   // a pad found with its button held (a reload, a book on it) waits for a release
  let frame = null;
  let name = '';
  const send = (next) => {
    if (next.active === last.active && next.x === last.x && next.y === last.y) return;
    last = next;
    onInput({ ...next });
  };
  const poll = () => {
    frame = null;
    const pad = get();
    if ((pad?.id ?? '') !== name) { name = pad?.id ?? ''; onPad(name); }
    if (!pad) { armed = false; send(idle()); return; }
    const read = readPad(pad);
    if (!read.held) armed = true;
    send(armed ? { x: read.x, y: read.y, active: read.active } : idle());
    frame = requestAnimationFrame(poll);
  };
  const start = () => { if (frame === null && !document.hidden) frame = requestAnimationFrame(poll); };
  addEventListener('gamepadconnected', start);
  addEventListener('gamepaddisconnected', () => { if (!get()) { armed = false; name = ''; onPad(''); send(idle()); } });
  document.addEventListener('visibilitychange', () => {
    if (document.hidden) { armed = false; send(idle()); } else start();
  });
  start();
  return {
    stop() { armed = false; send(idle()); },
    get state() { return { ...last, armed, name }; },
  };
}
