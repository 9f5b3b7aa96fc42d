// What the twin draws of a real robot besides its model: its point clouds (sensor_msgs/PointCloud2,
// thinned by the gateway to POINTS points: subscribe's `points`), its markers (visualization_msgs
// Marker and MarkerArray topics, every type: markers3d.js; DELETE, DELETEALL, lifetimes, frame-locked
// ones following their frame) and its goals (geometry_msgs/PoseStamped on a goal topic, as RViz's
// "2D Goal Pose" publishes: an arrow). Each is placed in its message's frame by TF (frames.js) as the
// message came; its paths (nav_msgs/Path) the map layer draws (map3d.js). The robot's own world view
// (NS/world/markers) is twin/main.js's. Topics of the twin's namespace (all, without one).
import * as THREE from 'three';
import { markerMesh, ADD, DELETE, DELETEALL } from './markers3d.js';
import { cloudPoints } from './clouds3d.js';

export const POINTS = 4000;          // points of a cloud drawn (what a phone's view shows usefully)
const CLOUD_EVERY = 250;             // ms: at most 4 clouds a second (4,000 points: 64 KB each)
const GOAL = /(^|\/)(goal|goal_pose)$/;
const MARKER = 'visualization_msgs/msg/Marker', MARKER_ARRAY = 'visualization_msgs/msg/MarkerArray';
const CLOUD = 'sensor_msgs/msg/PointCloud2', POSE = 'geometry_msgs/msg/PoseStamped';
const seconds = (d) => (d?.sec ?? 0) + (d?.nanosec ?? 0) / 1e9;

export class Drawables {
  constructor(twin, ns) {
    this.twin = twin;
    this.ns = ns;
    this.markers = new Map();     // `${topic} ${ns} ${id}` -> {object, frame, locked, until}
    this.clouds = new Map();      // topic -> {object, points}
    this.goals = new Map();       // topic -> arrow
    this.state = { clouds: {}, markers: 0, types: {}, goals: 0 };
    setInterval(() => this.expire(), 250);
  }

  mine(topic) { return !this.ns || topic.startsWith(`${this.ns}/`); }

  // Subscribes to every drawable topic of the graph (types: topic -> type).
  attach(ros, types) {
    for (const [topic, type] of types) {
      if (!this.mine(topic) || topic === `${this.ns}/world/markers`) continue;
      if (type === CLOUD) {   // CBOR: the points' bytes as they are (JSON's base64 is a third more)
        this.follow(ros, topic, type, (m) => this.onCloud(topic, m),
          { points: POINTS, throttle_rate: CLOUD_EVERY, queue_length: 1, compression: 'cbor' });
      }
      else if (type === MARKER_ARRAY) this.follow(ros, topic, type, (m) => this.onMarkers(topic, m.markers ?? []), { throttle_rate: 100 });
      else if (type === MARKER) this.follow(ros, topic, type, (m) => this.onMarkers(topic, [m]), { queue_length: 100 });
      else if (type === POSE && GOAL.test(topic)) this.follow(ros, topic, type, (m) => this.onGoal(topic, m), { queue_length: 1 });
    }
  }

  follow(ros, topic, type, fn, options) {
    ros.on(topic, (m) => fn(m.msg));
    ros.callOnConnection({ op: 'subscribe', id: `subscribe:${topic}:twin.draw`, topic, type, ...options });
  }

  // an object in a message's frame, where TF puts that frame now
  place(object, frame) {
    this.twin.frames.place(object, frame);
  }

  onCloud(topic, msg) {
    const old = this.clouds.get(topic);
    if (old) { this.twin.scene.remove(old.holder); old.points.geometry.dispose(); old.points.material.dispose(); }
    const points = cloudPoints(msg);
    const holder = new THREE.Group();
    holder.add(points);
    this.place(holder, msg.header?.frame_id);
    this.twin.scene.add(holder);
    this.clouds.set(topic, { holder, points });
    this.state.clouds[topic] = points.userData.count;
  }

  onMarkers(topic, markers) {
    const now = performance.now() / 1000;
    for (const m of markers) {
      if (m.action === DELETEALL) {
        for (const [key, it] of this.markers) {
          if (key.startsWith(`${topic} `) && (!m.ns || key.startsWith(`${topic} ${m.ns} `))) this.drop(key, it);
        }
        continue;
      }
      const key = `${topic} ${m.ns} ${m.id}`;
      const old = this.markers.get(key);
      if (old) this.drop(key, old);
      if (m.action === DELETE || m.action !== ADD && m.action !== 1) continue;   // ADD or MODIFY draw
      const object = markerMesh(m);
      if (!object) continue;
      const holder = new THREE.Group();
      holder.add(object);
      this.place(holder, m.header?.frame_id);
      this.twin.scene.add(holder);
      const life = seconds(m.lifetime);
      this.markers.set(key, { object: holder, frame: m.header?.frame_id, locked: Boolean(m.frame_locked), until: life > 0 ? now + life : Infinity, type: m.type });
    }
    this.count();
  }

  drop(key, it) {
    this.twin.scene.remove(it.object);
    this.markers.delete(key);
  }

  count() {
    this.state.markers = this.markers.size;
    const types = {};
    for (const it of this.markers.values()) types[it.type] = (types[it.type] ?? 0) + 1;
    this.state.types = types;
  }

  // markers past their lifetime go
  expire() {
    const now = performance.now() / 1000;
    let gone = false;
    for (const [key, it] of this.markers) if (it.until < now) { this.drop(key, it); gone = true; }
    if (gone) this.count();
  }

  // frame-locked markers follow their frame (called when TF changes)
  onTf() {
    for (const it of this.markers.values()) if (it.locked) this.place(it.object, it.frame);
  }

  onGoal(topic, msg) {
    let arrow = this.goals.get(topic);
    if (!arrow) {
      arrow = new THREE.Group();
      arrow.add(new THREE.ArrowHelper(new THREE.Vector3(1, 0, 0), new THREE.Vector3(), 0.6, 0x76ff03, 0.2, 0.12));
      this.goals.set(topic, arrow);
      this.twin.scene.add(arrow);
    }
    const p = msg.pose.position;
    const q = msg.pose.orientation.w || msg.pose.orientation.x || msg.pose.orientation.y || msg.pose.orientation.z
      ? msg.pose.orientation : { x: 0, y: 0, z: 0, w: 1 };   // an unset orientation
    const inFrame = new THREE.Group();
    this.place(inFrame, msg.header?.frame_id);
    const pose = new THREE.Matrix4().compose(new THREE.Vector3(p.x, p.y, p.z + 0.05), new THREE.Quaternion(q.x, q.y, q.z, q.w),
      new THREE.Vector3(1, 1, 1));
    inFrame.updateMatrix();
    pose.premultiply(inFrame.matrix).decompose(arrow.position, arrow.quaternion, new THREE.Vector3());
    this.state.goals = this.goals.size;
    this.state.goal = { topic, x: arrow.position.x, y: arrow.position.y };
  }
}
