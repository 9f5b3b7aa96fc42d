// The robot's map (nav_msgs/OccupancyGrid) on the twin's floor, and its paths (nav_msgs/Path):
// the grid becomes one texture (free light, occupied dark, unknown left out) on a plane placed
// at the map's origin in its frame. The page asks the gateway for the map made to measure (the
// ``image`` field of subscribe, MAP_SIZE cells a side at most, CBOR): a 4000x4000 map then costs
// ~250 KB an update, not 16 MB.
import * as THREE from 'three';

export const MAP_SIZE = 512;
const FREE = [207, 212, 222, 255], OCCUPIED = [24, 26, 32, 255], UNKNOWN = [0, 0, 0, 0];

// RGBA bytes of a grid: each cell by its occupancy (-1 unknown, 0 free .. 100 occupied).
export function gridPixels(width, height, data) {
  const px = new Uint8Array(width * height * 4);
  for (let i = 0; i < width * height; i++) {
    const v = data[i];
    const c = v < 0 || v === undefined ? UNKNOWN : v >= 65 ? OCCUPIED : v <= 25 ? FREE
      : FREE.map((f, k) => (k === 3 ? 255 : Math.round(f + (OCCUPIED[k] - f) * (v - 25) / 40)));
    px.set(c, i * 4);
  }
  return px;
}

export class MapLayer {
  constructor(scene, frames) {
    this.scene = scene;
    this.frames = frames;
    this.mesh = null;
    this.paths = new Map();
    this.info = null;
    this.frame = '';
  }

  onGrid(msg) {
    const { width, height, resolution, origin } = msg.info;
    if (!(width > 0 && height > 0 && resolution > 0)) return;
    const texture = new THREE.DataTexture(gridPixels(width, height, msg.data), width, height, THREE.RGBAFormat);
    texture.magFilter = THREE.NearestFilter;
    texture.needsUpdate = true;
    if (this.mesh) {
      this.scene.remove(this.mesh);
      this.plane.geometry.dispose();
      this.plane.material.map.dispose();
      this.plane.material.dispose();
    }
    const plane = new THREE.Mesh(new THREE.PlaneGeometry(width * resolution, height * resolution),
      new THREE.MeshBasicMaterial({ map: texture, transparent: true, depthWrite: false }));
    plane.position.set(width * resolution / 2, height * resolution / 2, 0);
    const grid = new THREE.Group();         // the grid's origin (info.origin) ...
    const p = origin.position, q = origin.orientation;
    grid.position.set(p.x, p.y, p.z + 0.002);
    grid.quaternion.set(q.x, q.y, q.z, q.w);
    grid.add(plane);
    this.mesh = new THREE.Group();          // ... in the map's frame
    this.mesh.add(grid);
    this.plane = plane;
    this.frame = msg.header?.frame_id ?? 'map';
    this.info = { width, height, resolution };
    this.scene.add(this.mesh);
    this.place();
  }

  onPath(topic, msg, colour = 0x4fc3f7) {
    const old = this.paths.get(topic);
    if (old) { this.scene.remove(old.line); old.line.geometry.dispose(); }
    const pts = (msg.poses ?? []).map((ps) => new THREE.Vector3(ps.pose.position.x, ps.pose.position.y, ps.pose.position.z + 0.02));
    const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(pts), new THREE.LineBasicMaterial({ color: colour }));
    this.paths.set(topic, { line, frame: msg.header?.frame_id ?? this.frame, points: pts.length });
    this.scene.add(line);
    this.place();
  }

  // Everything placed in its frame as TF now says (called when TF changes).
  place() {
    if (this.mesh) this.frames.place(this.mesh, this.frame);
    for (const p of this.paths.values()) this.frames.place(p.line, p.frame);
  }
}
