// The robot's own model from its URDF (urdf-loader), with its meshes: STL, Collada (.dae, with
// its materials and textures) and OBJ (with its .mtl) through three's own loaders, fetched from
// the gateway's /package/PKG/PATH (package:// and file:// URIs of the description). A mesh that
// cannot be fetched or read is drawn as a grey box where it belongs (the size of the link's
// collision box when it has one, else 10 cm) and named in the page's notice: never a blank page.
// Joints move from sensor_msgs/JointState (revolute, continuous, prismatic; by name).
import * as THREE from 'three';
import { URDFLoader, STLLoader, ColladaLoader, OBJLoader, MTLLoader } from 'three';
import { t } from '../i18n.js';
import { api } from '../link/api.js';

const PLACEHOLDER = 0x9097a8;

// The gateway's URL of a mesh named in a URDF ('' when it names no package file).
export function meshUrl(uri) {
  const s = String(uri).trim();
  let m = /^package:\/\/([^/]+)\/(.+)$/.exec(s);
  if (m) return `package/${m[1]}/${m[2]}`;
  m = /^file:\/\/(\/.*)$/.exec(s);
  if (m) {   // an installed package's share folder, else a folder of packages (--mesh-path)
    const path = decodeURI(m[1]);
    const share = /\/share\/([^/]+)\/(.+)$/.exec(path);
    if (share) return `package/${share[1]}/${share[2]}`;
    const pkg = /\/([^/]+)\/((?:meshes|urdf|materials|textures|models)\/.+)$/.exec(path);
    if (pkg) return `package/${pkg[1]}/${pkg[2]}`;
    return '';
  }
  return /^[a-z]+:/i.test(s) ? '' : s;
}

function placeholder(size) {
  const box = new THREE.Mesh(new THREE.BoxGeometry(...size),
    new THREE.MeshStandardMaterial({ color: PLACEHOLDER, transparent: true, opacity: 0.55 }));
  box.userData.placeholder = true;
  return box;
}

// [x, y, z] of the collision box of the link a visual belongs to (the nearest stand-in for the
// missing mesh's bounding box), else 10 cm.
function standInSize(visual) {
  const link = visual?.parent;
  const box = link?.urdfNode?.querySelector?.('collision box');
  const size = box?.getAttribute('size')?.trim().split(/\s+/).map(Number);
  return size?.length === 3 && size.every((v) => v > 0) ? size : [0.1, 0.1, 0.1];
}

function loadObj(url, manager, material, done, fail) {
  fetch(url).then((r) => (r.ok ? r.text() : Promise.reject(new Error(`${r.status} ${r.statusText}`)))).then((text) => {
    const lib = /^\s*mtllib\s+(.+?)\s*$/m.exec(text)?.[1];
    const finish = (materials) => {
      const loader = new OBJLoader(manager);
      if (materials) loader.setMaterials(materials);
      const obj = loader.parse(text);
      if (!materials && material) obj.traverse((o) => { if (o.isMesh) o.material = material; });
      done(obj);
    };
    if (!lib) { finish(null); return; }
    const base = url.slice(0, url.lastIndexOf('/') + 1);
    new MTLLoader(manager).setResourcePath(base).load(base + lib, (m) => { m.preload(); finish(m); }, undefined, () => finish(null));
  }).catch(fail);
}

/**
 * The model of a URDF text: {robot, group, joints, missing: Promise of [urls], body: material}.
 * onProblem(text) is told of every mesh drawn as a box.
 */
export function loadUrdf(xml, { onProblem = () => {} } = {}) {
  const manager = new THREE.LoadingManager();
  manager.setURLModifier((url) => meshUrl(url) || url);   // textures named package:// too
  const loader = new URDFLoader(manager);
  const missing = [];
  const urdfMaterials = new Set();   // the URDF's <material> colours, sRGB as RViz shows them
  let pending = 0;
  let settle;
  const settled = new Promise((resolve) => { settle = resolve; });
  const oneDone = () => { pending -= 1; if (pending === 0) settle(missing); };
  loader.packages = (pkg) => `package://${pkg}`;     // kept as written: meshUrl maps them
  loader.loadMeshCb = (path, mgr, material, done) => {
    pending += 1;
    if (material) urdfMaterials.add(material);
    const url = meshUrl(path.replace(/^package:\/\/package:\/\//, 'package://'));
    const holder = new THREE.Group();
    done(holder);                                     // placed now, filled when it arrives
    const fill = (obj) => { holder.add(obj); oneDone(); };
    const fail = (why) => {
      missing.push(path);
      onProblem(`${path}: ${why?.message ?? why ?? t('urdf.cannot.load')}`);
      holder.add(placeholder(standInSize(holder.parent)));
      oneDone();
    };
    const ext = (/\.([a-z0-9]+)$/i.exec(url)?.[1] ?? '').toLowerCase();
    if (!url) { fail(t('urdf.not.served')); return; }
    if (ext === 'stl') {
      new STLLoader(mgr).load(url, (geom) => {
        geom.computeVertexNormals();   // flat, from the triangles: exporters often write 0 0 0 normals
        fill(new THREE.Mesh(geom, material ?? new THREE.MeshPhongMaterial()));
      }, undefined, fail);
    } else if (ext === 'dae') {
      new ColladaLoader(mgr).load(url, (dae) => {
        // ROS reads Collada as assimp does: a Z-up file as it is, a Y-up one turned to Z-up
        dae.scene.rotation.set(dae.scene.rotation.x === 0 ? Math.PI / 2 : 0, 0, 0);
        fill(dae.scene);
      }, undefined, fail);
    } else if (ext === 'obj') {
      loadObj(url, mgr, material, fill, fail);
    } else {
      fail(t('urdf.no.loader', { ext: ext || '?' }));
    }
  };
  const robot = loader.parse(xml);
  robot.rotation.set(0, 0, 0);
  robot.traverse((o) => { if (o.isMesh && o.material) urdfMaterials.add(o.material); });   // primitives
  for (const m of urdfMaterials) m.color?.convertSRGBToLinear();
  if (pending === 0) settle(missing);
  const group = new THREE.Group();
  group.add(robot);
  let body = null;
  robot.traverse((o) => { if (!body && o.isMesh && o.material?.emissive) body = o.material; });
  return {
    kind: 'urdf', robot, group, wheels: wheelsOf(robot), scanHeight: 0.2, loaded: settled, missing,
    get body() { return body ?? findBody(robot) ?? new THREE.MeshStandardMaterial(); },
  };
}

// {left, right}: a material of its own for each wheel link's first primitive (the wheels that
// take their motor's temperature colour), when the links are named so (left_wheel_link ...).
function wheelsOf(robot) {
  const wheels = {};
  for (const [name, link] of Object.entries(robot.links ?? {})) {
    const side = /wheel/i.test(name) && (/left/i.test(name) ? 'left' : /right/i.test(name) ? 'right' : null);
    if (!side || wheels[side]) continue;
    let mesh = null;
    link.traverse((o) => { if (!mesh && o.isMesh) mesh = o; });
    if (mesh) { mesh.material = mesh.material.clone(); wheels[side] = mesh; }
  }
  return wheels;
}

function findBody(robot) {
  let found = null;
  robot.traverse((o) => { if (!found && o.isMesh && !o.userData.placeholder && o.material?.emissive) found = o.material; });
  return found;
}

// Joint positions by name from a sensor_msgs/JointState (joints the model lacks are skipped);
// returns how many were set.
export function applyJointState(robot, msg) {
  let n = 0;
  const names = msg.name ?? [];
  const positions = msg.position ?? [];
  names.forEach((name, i) => {
    const joint = robot.joints?.[name] ?? robot.joints?.[String(name).split('/').pop()];
    const value = Number(positions[i]);
    if (!joint || !Number.isFinite(value)) return;
    if (!['revolute', 'continuous', 'prismatic'].includes(joint.jointType)) return;
    joint.setJointValue(value);
    n += 1;
  });
  return n;
}

// The robot's description as the gateway finds it for namespace ns: {urdf, from} with from one
// of '--urdf', 'topic', 'parameter' (urdf '' and from null when it has none; error: why it could
// not read or expand one). Always answered (a gateway without --urdf has no /urdf to ask for).
export async function description(ns = '') {
  try {
    const body = await api('api/description', { query: { ns } });
    return { urdf: body?.urdf || '', from: body?.from ?? null, error: body?.error ?? null };
  } catch (e) { return { urdf: '', from: null, error: e.message }; }   // an ApiError's message: the gateway's words
}

// Whether a description is xacro (the gateway expands it), not URDF.
export function isXacro(text) {
  return /xmlns:xacro\s*=|<xacro:/.test(String(text));
}
