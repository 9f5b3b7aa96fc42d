// A nav_msgs/OccupancyGrid as pixels, for the 3D twin's floor (map3d.js) and the 2D world view
// (worldview.js): free light, occupied dark, unknown transparent; row 0 is the map's origin row.
// The pages ask the gateway for the map made to measure (the ``image`` field of subscribe, at most
// MAP_SIZE cells a side, CBOR: one byte a cell): a 4000x4000 map costs ~250 KB an update, not 16 MB.
export const MAP_SIZE = 512;
const FREE = [207, 212, 222, 255], OCCUPIED = [24, 26, 32, 255], UNKNOWN = [0, 0, 0, 0];

// RGBA bytes of a grid: each cell by its occupancy (-1 unknown, 0 free .. 100 occupied).
export function gridPixels(width, height, data) {
  const px = new Uint8ClampedArray(width * height * 4);
  for (let i = 0; i < width * height; i++) {
    const v = data[i];
    const c = v < 0 || v === undefined ? UNKNOWN : v >= 65 ? OCCUPIED : v <= 25 ? FREE
      : FREE.map((f, k) => (k === 3 ? 255 : Math.round(f + (OCCUPIED[k] - f) * (v - 25) / 40)));
    px.set(c, i * 4);
  }
  return px;
}

// The subscribe op of a map made to measure.
export function mapSubscribe(topic, id) {
  return { op: 'subscribe', id, topic, type: 'nav_msgs/msg/OccupancyGrid', compression: 'cbor', queue_length: 1,
    image: { width: MAP_SIZE, height: MAP_SIZE } };
}

// A canvas of the grid, with where it lies: {canvas, frame, x, y, yaw, w, h} (metres, radians).
export function gridImage(msg) {
  const { width, height, resolution, origin } = msg.info;
  if (!(width > 0 && height > 0 && resolution > 0)) return null;
  const canvas = document.createElement('canvas');
  canvas.width = width;
  canvas.height = height;
  canvas.getContext('2d').putImageData(new ImageData(gridPixels(width, height, msg.data), width, height), 0, 0);
  const q = origin.orientation;
  return { canvas, frame: msg.header?.frame_id || 'map', x: origin.position.x, y: origin.position.y,
    yaw: Math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)),
    w: width * resolution, h: height * resolution };
}
