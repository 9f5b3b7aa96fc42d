// visualization_msgs/Marker as three.js objects, every type RViz draws: arrows (by pose, or from
// points[0] to points[1]), cubes, spheres, cylinders, line strips and lists, cube and sphere
// lists, points, text facing the viewer, meshes (package:// through the gateway's /package/, a
// box where one cannot be read) and triangle lists; the marker's colour, or a colour per point.
// Sizes as RViz reads `scale`; objects in the marker's frame (the caller places them by TF).
import * as THREE from 'three';
import { STLLoader, ColladaLoader, OBJLoader } from 'three';
import { meshUrl } from './urdf.js';

export const TYPES = { ARROW: 0, CUBE: 1, SPHERE: 2, CYLINDER: 3, LINE_STRIP: 4, LINE_LIST: 5, CUBE_LIST: 6,
  SPHERE_LIST: 7, POINTS: 8, TEXT_VIEW_FACING: 9, MESH_RESOURCE: 10, TRIANGLE_LIST: 11 };
export const ADD = 0, DELETE = 2, DELETEALL = 3;

const colourOf = (c) => new THREE.Color(c?.r ?? 1, c?.g ?? 1, c?.b ?? 1);
const vec = (p) => new THREE.Vector3(p.x, p.y, p.z);
const material = (m, extra = {}) => {
  const a = m.color?.a ?? 1;
  return new THREE.MeshStandardMaterial({ color: colourOf(m.color), transparent: a < 1, opacity: a, roughness: 0.6, ...extra });
};
// per-point colours, when the marker has one for each point
const pointColours = (m) => (m.colors?.length === m.points?.length && m.points?.length
  ? new THREE.Float32BufferAttribute(m.colors.flatMap((c) => [c.r, c.g, c.b]), 3) : null);

function arrow(m) {
  const g = new THREE.Group();
  let from = new THREE.Vector3(), to, shaft, head, headLength;
  if (m.points?.length >= 2) {
    from = vec(m.points[0]);
    to = vec(m.points[1]);
    shaft = m.scale.x;
    head = m.scale.y;
    headLength = m.scale.z || 0.23 * from.distanceTo(to);
  } else {
    to = new THREE.Vector3(m.scale.x, 0, 0);
    shaft = m.scale.y;
    head = 2 * m.scale.y;
    headLength = 0.23 * m.scale.x;
  }
  const length = from.distanceTo(to);
  if (!(length > 0)) return g;
  const mat = material(m);
  const body = new THREE.Mesh(new THREE.CylinderGeometry(shaft / 2, shaft / 2, Math.max(length - headLength, 1e-4), 16), mat);
  const tip = new THREE.Mesh(new THREE.ConeGeometry(head / 2, Math.min(headLength, length), 16), mat);
  body.position.y = Math.max(length - headLength, 1e-4) / 2;
  tip.position.y = length - Math.min(headLength, length) / 2;
  const holder = new THREE.Group();   // three's cylinders stand on y: turn y onto the arrow's direction
  holder.add(body, tip);
  holder.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), to.clone().sub(from).normalize());
  holder.position.copy(from);
  g.add(holder);
  return g;
}

function list(m, geometry) {
  const n = m.points?.length ?? 0;
  const mesh = new THREE.InstancedMesh(geometry, material(m, { color: 0xffffff }), Math.max(1, n));
  const colours = pointColours(m);
  const base = colourOf(m.color);
  const at = new THREE.Matrix4();
  for (let i = 0; i < n; i++) {
    at.makeScale(m.scale.x, m.scale.y, m.scale.z).setPosition(vec(m.points[i]));
    mesh.setMatrixAt(i, at);
    mesh.setColorAt(i, colours ? new THREE.Color().fromArray(colours.array, 3 * i) : base);
  }
  mesh.count = n;
  return mesh;
}

function text(m) {
  const canvas = document.createElement('canvas');
  const g = canvas.getContext('2d');
  const size = 64;
  g.font = `${size}px system-ui, sans-serif`;
  const lines = String(m.text ?? '').split('\n');
  canvas.width = Math.max(4, ...lines.map((l) => Math.ceil(g.measureText(l).width))) + 8;
  canvas.height = lines.length * size * 1.2;
  g.font = `${size}px system-ui, sans-serif`;
  g.fillStyle = `#${colourOf(m.color).getHexString()}`;
  g.textBaseline = 'top';
  lines.forEach((l, i) => g.fillText(l, 4, i * size * 1.2));
  const sprite = new THREE.Sprite(new THREE.SpriteMaterial({ map: new THREE.CanvasTexture(canvas), transparent: true,
    opacity: m.color?.a ?? 1, depthTest: false }));
  const height = (m.scale.z || 0.1) * lines.length;   // scale.z: the height of a capital letter
  sprite.scale.set(height * (canvas.width / canvas.height), height, 1);
  return sprite;
}

function mesh(m) {
  const g = new THREE.Group();
  const box = () => new THREE.Mesh(new THREE.BoxGeometry(1, 1, 1), material(m, { wireframe: true }));
  const url = meshUrl(m.mesh_resource ?? '');
  const ext = (/\.([a-z0-9]+)$/i.exec(url)?.[1] ?? '').toLowerCase();
  const own = m.mesh_use_embedded_materials ? null : material(m);
  const fill = (object) => {
    if (own) object.traverse?.((o) => { if (o.isMesh) o.material = own; });
    g.add(object);
  };
  const fail = () => g.add(box());
  if (ext === 'stl') new STLLoader().load(url, (geom) => { geom.computeVertexNormals(); fill(new THREE.Mesh(geom, own ?? material(m))); }, undefined, fail);
  else if (ext === 'dae') new ColladaLoader().load(url, (dae) => fill(dae.scene), undefined, fail);
  else if (ext === 'obj') new OBJLoader().load(url, fill, undefined, fail);
  else fail();
  g.scale.set(m.scale.x || 1, m.scale.y || 1, m.scale.z || 1);
  return g;
}

// The three.js object of a marker in its own frame (its pose applied), or null for none.
export function markerMesh(m) {
  const T = TYPES;
  let obj;
  switch (m.type) {
    case T.ARROW: obj = arrow(m); break;
    case T.CUBE: obj = new THREE.Mesh(new THREE.BoxGeometry(m.scale.x, m.scale.y, m.scale.z), material(m)); break;
    case T.SPHERE: obj = new THREE.Mesh(new THREE.SphereGeometry(0.5, 24, 16), material(m)); obj.scale.set(m.scale.x, m.scale.y, m.scale.z); break;
    case T.CYLINDER: {
      const c = new THREE.Mesh(new THREE.CylinderGeometry(0.5, 0.5, 1, 24), material(m));
      c.rotation.x = Math.PI / 2;   // RViz's cylinders stand on z
      obj = new THREE.Group();
      obj.add(c);
      obj.scale.set(m.scale.x, m.scale.y, m.scale.z);
      break;
    }
    case T.LINE_STRIP: case T.LINE_LIST: {
      const geom = new THREE.BufferGeometry().setFromPoints((m.points ?? []).map(vec));
      const colours = pointColours(m);
      if (colours) geom.setAttribute('color', colours);
      const mat = new THREE.LineBasicMaterial({ color: colours ? 0xffffff : colourOf(m.color), vertexColors: Boolean(colours),
        transparent: (m.color?.a ?? 1) < 1, opacity: m.color?.a ?? 1 });
      obj = m.type === T.LINE_STRIP ? new THREE.Line(geom, mat) : new THREE.LineSegments(geom, mat);
      break;
    }
    case T.CUBE_LIST: obj = list(m, new THREE.BoxGeometry(1, 1, 1)); break;
    case T.SPHERE_LIST: obj = list(m, new THREE.SphereGeometry(0.5, 12, 8)); break;
    case T.POINTS: {
      const geom = new THREE.BufferGeometry().setFromPoints((m.points ?? []).map(vec));
      const colours = pointColours(m);
      if (colours) geom.setAttribute('color', colours);
      obj = new THREE.Points(geom, new THREE.PointsMaterial({ size: m.scale.x || 0.05, color: colours ? 0xffffff : colourOf(m.color),
        vertexColors: Boolean(colours) }));
      break;
    }
    case T.TEXT_VIEW_FACING: obj = text(m); break;
    case T.MESH_RESOURCE: obj = mesh(m); break;
    case T.TRIANGLE_LIST: {
      const geom = new THREE.BufferGeometry().setFromPoints((m.points ?? []).map(vec));
      const colours = pointColours(m);
      if (colours) geom.setAttribute('color', colours);
      geom.computeVertexNormals();
      obj = new THREE.Mesh(geom, material(m, { side: THREE.DoubleSide, vertexColors: Boolean(colours), ...(colours ? { color: 0xffffff } : {}) }));
      obj.scale.set(m.scale.x || 1, m.scale.y || 1, m.scale.z || 1);
      break;
    }
    default: return null;
  }
  const outer = new THREE.Group();   // the pose, then what the type put inside
  const p = m.pose?.position ?? { x: 0, y: 0, z: 0 }, q = m.pose?.orientation ?? { x: 0, y: 0, z: 0, w: 1 };
  outer.position.set(p.x, p.y, p.z);
  outer.quaternion.set(q.x, q.y, q.z, q.w);
  if (q.x === 0 && q.y === 0 && q.z === 0 && q.w === 0) outer.quaternion.identity();   // an unset orientation
  outer.add(obj);
  outer.userData.type = m.type;
  return outer;
}
