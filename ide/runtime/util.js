// Pure helpers shared by the runtime, the IDE and the teleop page.
// The generated Python carries the same functions (runtime/rosgate_runtime.py).

// Formats a value for `log` the same way the Python runtime does.
export function fmt(v) {
  if (typeof v === 'string') return v;
  return repr(v);
}

function repr(v) {
  if (v === null || v === undefined) return 'null';
  if (typeof v === 'boolean') return v ? 'true' : 'false';
  if (typeof v === 'number') {
    if (!Number.isFinite(v)) return Number.isNaN(v) ? 'nan' : (v > 0 ? 'inf' : '-inf');
    return String(v);
  }
  if (typeof v === 'string') return JSON.stringify(v);
  if (Array.isArray(v) || ArrayBuffer.isView(v)) return `[${Array.from(v, repr).join(', ')}]`;
  if (typeof v === 'object') {
    return `{${Object.entries(v).map(([k, x]) => `${JSON.stringify(k)}: ${repr(x)}`).join(', ')}}`;
  }
  return String(v);
}

// field({pose: {x: 1}}, 'pose.x') -> 1; 'ranges.0' indexes arrays.
export function field(obj, path) {
  let v = obj;
  for (const part of String(path).split('.').filter(Boolean)) {
    if (v === null || v === undefined) {
      throw new Error(`no field '${path}' in message`);
    }
    if (!(part in Object(v))) throw new Error(`no field '${part}' of '${path}' in message`);
    v = v[part];
  }
  return v;
}

// One number (or value) out of a message for a "make a block" reader: `selector` is a field
// path ('range_max'), or a reducer over a list field: 'min:ranges', 'max:ranges', 'mean:ranges'
// (over the finite numbers; NaN and inf arrive as null) or 'item:ranges' (item `index`, from 0;
// negative counts from the end). min of nothing is Infinity, max -Infinity, mean NaN.
export function pick(msg, selector, index = 0) {
  const m = /^(min|max|mean|item):(.+)$/.exec(String(selector));
  if (!m) return field(msg, selector);
  const [, how, path] = m;
  const list = field(msg, path);
  if (!Array.isArray(list) && !ArrayBuffer.isView(list)) throw new Error(`'${path}' is not a list`);
  if (how === 'item') {
    const i = Math.trunc(index === null || index === undefined ? NaN : Number(index));
    if (!(i >= -list.length && i < list.length)) throw new Error(`no item ${fmt(index)} in '${path}' (it has ${list.length})`);
    return list[i < 0 ? list.length + i : i];
  }
  let n = 0;
  let acc = how === 'min' ? Infinity : how === 'max' ? -Infinity : 0;
  for (const v of list) {
    if (typeof v !== 'number' || !Number.isFinite(v)) continue;
    n += 1;
    if (how === 'min') { if (v < acc) acc = v; } else if (how === 'max') { if (v > acc) acc = v; } else acc += v;
  }
  return how === 'mean' ? (n ? acc / n : NaN) : acc;
}

// Heading in radians from a geometry_msgs/Quaternion.
export function yaw(q) {
  const { x = 0, y = 0, z = 0, w = 1 } = q ?? {};
  return Math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));
}

// Smallest a - b, wrapped into (-pi, pi] in closed form (a loop of 2*pi steps never ends for
// 1e20); NaN when either angle is not finite (an infinite angle has no direction), as in Python.
export function angleDiff(a, b) {
  const tau = 2 * Math.PI;
  let d = Number(a) - Number(b);
  if (!Number.isFinite(d)) return NaN;
  d %= tau;                      // (-tau, tau), the sign of a - b
  if (d > Math.PI) d -= tau;
  else if (d <= -Math.PI) d += tau;
  return d;
}

// Nearest valid range of a sensor_msgs/LaserScan within +-window/2 degrees of `degrees`
// (0 = straight ahead, 90 = left). Infinity when nothing is in range.
export function rangeAt(scan, degrees = 0, window = 20) {
  const centre = Number(degrees) * Math.PI / 180;
  const half = Math.abs(Number(window)) * Math.PI / 360;
  let best = Infinity;
  const ranges = scan?.ranges ?? [];
  for (let i = 0; i < ranges.length; i++) {
    const r = ranges[i];
    if (r === null || !Number.isFinite(r) || r < scan.range_min || r > scan.range_max) continue;
    const a = scan.angle_min + i * scan.angle_increment;
    if (Math.abs(angleDiff(a, centre)) <= half && r < best) best = r;
  }
  return best;
}

export function isVelocityType(type) {
  return /^geometry_msgs\/(msg\/)?Twist(Stamped)?$/.test(type);
}

export function zeroVelocity(type) {
  const t = { linear: { x: 0, y: 0, z: 0 }, angular: { x: 0, y: 0, z: 0 } };
  return /TwistStamped$/.test(type) ? { header: { frame_id: '' }, twist: t } : t;
}

// {x, y, theta} from a turtlesim/Pose, nav_msgs/Odometry or geometry_msgs/Pose(Stamped).
export function poseOf(msg, type = '') {
  if (/turtlesim/.test(type) || (msg && 'theta' in msg)) {
    return { x: msg.x, y: msg.y, theta: msg.theta };
  }
  let p = msg;
  if (p?.pose?.pose) p = p.pose.pose;      // Odometry, PoseWithCovarianceStamped
  else if (p?.pose) p = p.pose;            // PoseStamped
  return { x: p.position.x, y: p.position.y, theta: yaw(p.orientation) };
}

// A robot namespace as typed ('s07', '/s07/', ' / ') -> '/s07', or '' for none.
export function normNamespace(text) {
  const parts = String(text ?? '').split('/').map((s) => s.trim()).filter(Boolean);
  return parts.length ? `/${parts.join('/')}` : '';
}

// A robot block's name in a namespace: ('/s07', '/turtle1/cmd_vel') -> '/s07/turtle1/cmd_vel';
// a relative name is in the namespace too, and under '/' without one: ('', 'odom') -> '/odom'.
export function withNamespace(ns, name) {
  name = String(name);
  return `${normNamespace(ns)}${name.startsWith('/') ? '' : '/'}${name}`;
}
