// sensor_msgs/PointCloud2 for the twin: the points a subscriber asked the gateway for (subscribe's
// `points`: at most so many, x y z float32 and a colour or intensity, bridge/clouds.py), or a whole
// cloud from a gateway that sends it as it is, read by its fields' offsets, types and byte order.
// Coloured by its rgb field, else its intensity, else its height.
import * as THREE from 'three';

const READ = { 1: ['getInt8', 1], 2: ['getUint8', 1], 3: ['getInt16', 2], 4: ['getUint16', 2], 5: ['getInt32', 4],
  6: ['getUint32', 4], 7: ['getFloat32', 4], 8: ['getFloat64', 8] };   // sensor_msgs/PointField datatypes

export function bytesOf(data) {
  if (data instanceof Uint8Array) return data;
  if (ArrayBuffer.isView(data)) return new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
  if (Array.isArray(data)) return Uint8Array.from(data);
  const raw = atob(String(data ?? ''));
  const out = new Uint8Array(raw.length);
  for (let i = 0; i < raw.length; i++) out[i] = raw.charCodeAt(i);
  return out;
}

// {positions: Float32Array (x y z ...), colours: Float32Array (r g b ...), count} of a cloud's finite points.
export function readCloud(msg) {
  const bytes = bytesOf(msg.data);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const step = msg.point_step, n = Math.min(msg.width * msg.height, Math.floor(bytes.byteLength / step));
  const little = !msg.is_bigendian;
  const field = (name) => msg.fields.find((f) => f.name === name && READ[f.datatype]);
  const [fx, fy, fz] = ['x', 'y', 'z'].map(field);
  if (!fx || !fy || !fz) return { positions: new Float32Array(0), colours: new Float32Array(0), count: 0 };
  const get = (f) => { const [fn] = READ[f.datatype]; return (i) => view[fn](i * step + f.offset, little); };
  const gx = get(fx), gy = get(fy), gz = get(fz);
  const rgb = field('rgb') ?? field('rgba'), intensity = field('intensity');
  const gi = intensity ? get(intensity) : gz;
  const positions = new Float32Array(3 * n), colours = new Float32Array(3 * n);
  let count = 0, lo = Infinity, hi = -Infinity;
  const shade = new Float32Array(n);
  for (let i = 0; i < n; i++) {
    const x = gx(i), y = gy(i), z = gz(i);
    if (!Number.isFinite(x) || !Number.isFinite(y) || !Number.isFinite(z)) continue;
    positions[3 * count] = x;
    positions[3 * count + 1] = y;
    positions[3 * count + 2] = z;
    if (rgb) {
      const packed = view.getUint32(i * step + rgb.offset, little);   // 0x00RRGGBB, as PCL packs it
      colours.set([((packed >> 16) & 255) / 255, ((packed >> 8) & 255) / 255, (packed & 255) / 255], 3 * count);
    } else {
      const v = gi(i);
      shade[count] = v;
      if (v < lo) lo = v;
      if (v > hi) hi = v;
    }
    count += 1;
  }
  if (!rgb) {
    const c = new THREE.Color();
    for (let i = 0; i < count; i++) {
      c.setHSL(0.66 * (1 - (hi > lo ? (shade[i] - lo) / (hi - lo) : 0.5)), 0.9, 0.55);   // blue (low) to red (high)
      colours.set([c.r, c.g, c.b], 3 * i);
    }
  }
  return { positions: positions.subarray(0, 3 * count), colours: colours.subarray(0, 3 * count), count };
}

// The cloud as three.js points (sized for a lidar seen from a few metres away).
export function cloudPoints(msg, size = 0.04) {
  const { positions, colours, count } = readCloud(msg);
  const geom = new THREE.BufferGeometry();
  geom.setAttribute('position', new THREE.BufferAttribute(positions, 3));
  geom.setAttribute('color', new THREE.BufferAttribute(colours, 3));
  const points = new THREE.Points(geom, new THREE.PointsMaterial({ size, vertexColors: true }));
  points.userData.count = count;
  return points;
}
