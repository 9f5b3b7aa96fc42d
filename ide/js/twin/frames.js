// TF for the twin: the newest transform of each frame from /tf and /tf_static (tf2_msgs), and
// where a frame is in the root of its tree (world, map or odom: the frame with no parent), so
// the robot's base link, its map and its paths are drawn where TF says. Frame names are kept as
// TF writes them, without a leading '/'.
import * as THREE from 'three';

const clean = (f) => String(f ?? '').replace(/^\/+/, '');

export class Frames {
  constructor() { this.parents = new Map(); this.version = 0; }

  // a tf2_msgs/TFMessage
  update(msg) {
    for (const t of msg.transforms ?? []) {
      const child = clean(t.child_frame_id), parent = clean(t.header?.frame_id);
      if (!child || !parent || child === parent) continue;
      const tr = t.transform.translation, q = t.transform.rotation;
      this.parents.set(child, {
        parent,
        matrix: new THREE.Matrix4().compose(new THREE.Vector3(tr.x, tr.y, tr.z),
          new THREE.Quaternion(q.x, q.y, q.z, q.w), new THREE.Vector3(1, 1, 1)),
      });
    }
    this.version += 1;
  }

  has(frame) { return this.parents.has(clean(frame)); }

  // The root frame of a frame's tree.
  root(frame) {
    let f = clean(frame);
    for (let i = 0; i < 64 && this.parents.has(f); i++) f = this.parents.get(f).parent;
    return f;
  }

  // A frame's pose in its tree's root as a Matrix4 (identity for a root or an unknown frame).
  matrix(frame) {
    const m = new THREE.Matrix4();
    let f = clean(frame);
    for (let i = 0; i < 64 && this.parents.has(f); i++) {
      const link = this.parents.get(f);
      m.premultiply(link.matrix);
      f = link.parent;
    }
    return m;
  }

  // Places a three.js object at a frame (position and orientation), when TF knows the frame.
  place(object, frame) {
    if (!this.has(frame)) return false;
    this.matrix(frame).decompose(object.position, object.quaternion, new THREE.Vector3());
    return true;
  }
}
