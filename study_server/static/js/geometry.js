// Poses on support surfaces, as the engine defines them (scenesuggest/scenes/poses.py, surfaces.py): attaching a
// face of an object's canonical box (bottom centred at the origin, +Y up, +Z front, metres) to a surface,
// turning it about the surface normal, and classifying the surface a click landed on.
import * as THREE from "three";

const FACE_NORMALS = {
  bottom: [0, -1, 0], top: [0, 1, 0], front: [0, 0, 1], back: [0, 0, -1], left: [1, 0, 0], right: [-1, 0, 0],
};
const FACE_CENTRE = {
  bottom: [0, 0, 0], top: [0, 1, 0], front: [0, 0.5, 0.5], back: [0, 0.5, -0.5], left: [0.5, 0.5, 0], right: [-0.5, 0.5, 0],
};
const FACE_REFERENCE = { bottom: [0, 0, 1], top: [0, 0, 1], front: [0, 1, 0], back: [0, 1, 0], left: [0, 1, 0], right: [0, 1, 0] };
const HORIZONTAL_COS = Math.cos(Math.PI / 4);

function faceCentre(face, size) {
  const f = FACE_CENTRE[face];
  return new THREE.Vector3(f[0] * size[0], f[1] * size[1], f[2] * size[2]);
}

export function isHorizontal(normal) {
  return Math.abs(normal.y) / normal.length() > HORIZONTAL_COS;
}

export function surfaceDirection(normal) {
  const y = normal.y / normal.length();
  return y > HORIZONTAL_COS ? "up" : y < -HORIZONTAL_COS ? "down" : "vertical";
}

/** up/down/vertical × interior/exterior of a contact on a parent (transform, canonical size). */
export function surfaceType(parentMatrix, parentSize, point, normal) {
  const inv = parentMatrix.clone().invert();
  const p = point.clone().applyMatrix4(inv);
  const n = normal.clone().applyMatrix3(new THREE.Matrix3().setFromMatrix4(parentMatrix).transpose()).normalize();
  const a = [Math.abs(n.x), Math.abs(n.y), Math.abs(n.z)];
  const axis = a.indexOf(Math.max(...a));
  const comp = ["x", "y", "z"][axis];
  const lo = [-parentSize[0] / 2, 0, -parentSize[2] / 2];
  const hi = [parentSize[0] / 2, parentSize[1], parentSize[2] / 2];
  const outer = n[comp] > 0 ? hi[axis] : lo[axis];
  const slack = 0.1 * parentSize[axis] + 0.01;
  return `${surfaceDirection(normal)}_${Math.abs(p[comp] - outer) <= slack ? "exterior" : "interior"}`;
}

/** Attachment by geometry: hang from ceilings by the top, stand on the bottom, on walls by the back (flat
 * things) or a side (thin deep things). */
export function geometricFace(size, normal) {
  const d = surfaceDirection(normal);
  if (d === "down") return "top";
  if (d === "up") return "bottom";
  const [sx, sy, sz] = size;
  return sz <= sx || sz <= 0.5 * sy ? "back" : "right";
}

const OPPOSITE = 1e-8;

function rotationBetween(a, b) {
  // opposite within OPPOSITE (scenesuggest/scenes/poses.py, the same; three.js's own test is this one too): a half
  // turn about +X for a top or bottom face, +Y for a side face (it stays upright)
  const dot = a.dot(b);
  if (dot + 1 < OPPOSITE) {
    const axis = Math.abs(a.y) > 0.5 ? new THREE.Vector3(1, 0, 0) : new THREE.Vector3(0, 1, 0);
    return new THREE.Quaternion().setFromAxisAngle(axis, Math.PI);
  }
  return new THREE.Quaternion().setFromUnitVectors(a, b);
}

/** The rotation taking a face's outward normal onto −normal (α = 0); horizontal-to-horizontal turns are
 * about +Y so that wall objects stay upright. */
export function attachRotation(face, normal) {
  const a = new THREE.Vector3(...FACE_NORMALS[face]);
  const b = normal.clone().normalize().negate();
  if (Math.abs(a.y) < 1e-9 && Math.abs(b.y) < 1e-6) {
    const angle = Math.atan2(a.z * b.x - a.x * b.z, a.x * b.x + a.z * b.z);
    return new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(0, 1, 0), angle);
  }
  return rotationBetween(a, b);
}

/** canonical → world: ``face`` on the plane at ``point``, turned by ``alpha`` radians about the normal. */
export function placement(point, normal, face, size, alpha = 0) {
  const n = normal.clone().normalize();
  const q = new THREE.Quaternion().setFromAxisAngle(n, alpha).multiply(attachRotation(face, n));
  return poseMatrix(point, q, face, size);
}

/** canonical → world from a rotation and the attached face's centre at ``point``. */
export function poseMatrix(point, quaternion, face, size) {
  const m = new THREE.Matrix4().compose(new THREE.Vector3(), quaternion, new THREE.Vector3(1, 1, 1));
  const offset = faceCentre(face, size).applyMatrix4(m).negate().add(point);
  m.setPosition(offset);
  return m;
}

export function rotationOf(matrix) {
  const q = new THREE.Quaternion();
  matrix.decompose(new THREE.Vector3(), q, new THREE.Vector3());
  return q;
}

/** Heading (radians about the normal) of an object attached by ``face``: the angle of its in-plane
 * reference vector from the plane's zero direction (+Z on floors, +Y on walls). */
export function heading(matrix, face, normal) {
  const n = normal.clone().normalize();
  const zero = isHorizontal(n) ? new THREE.Vector3(0, 0, 1) : new THREE.Vector3(0, 1, 0);
  zero.addScaledVector(n, -zero.dot(n)).normalize();
  const d = new THREE.Vector3(...FACE_REFERENCE[face]).applyQuaternion(rotationOf(matrix));
  d.addScaledVector(n, -d.dot(n));
  return Math.atan2(new THREE.Vector3().crossVectors(zero, d).dot(n), zero.dot(d));
}

export function toColumnMajor(matrix) { return Array.from(matrix.elements); }
export function fromColumnMajor(values) { return new THREE.Matrix4().fromArray(values); }
