// The robot's map (nav_msgs/OccupancyGrid) on the twin's floor, and its paths (nav_msgs/Path):
// the grid becomes one texture (grid.js) on a plane placed at the map's origin in its frame.
import * as THREE from 'three';
import { gridPixels } from '../views/grid.js';

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
    const texture = new THREE.DataTexture(new Uint8Array(gridPixels(width, height, msg.data).buffer), width, height, THREE.RGBAFormat);
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
