// Evaluates the client's geometry module (study_server/static/js/geometry.js) on cases read as JSON from stdin,
// for the parity test with the engine (tests/test_geometry_parity.py). Input: a list of [function, arguments];
// output: the list of results, in order. Vectors are [x, y, z] (metres, world frame, +Y up); matrices are 4×4 as
// 16 numbers in column-major order; rotations are answered as the 4×4 matrix of the rotation; angles in radians.
import * as THREE from "three";
import * as G from "../../study_server/static/js/geometry.js";

const vec = (v) => new THREE.Vector3(...v);
const mat = (values) => G.fromColumnMajor(values);
const rotationMatrix = (q) => G.toColumnMajor(new THREE.Matrix4().makeRotationFromQuaternion(q));

const CASES = {
  isHorizontal: ({ normal }) => G.isHorizontal(vec(normal)),
  surfaceDirection: ({ normal }) => G.surfaceDirection(vec(normal)),
  surfaceType: ({ parent, parentSize, point, normal }) => G.surfaceType(mat(parent), parentSize, vec(point), vec(normal)),
  geometricFace: ({ size, normal }) => G.geometricFace(size, vec(normal)),
  attachRotation: ({ face, normal }) => rotationMatrix(G.attachRotation(face, vec(normal))),
  placement: ({ point, normal, face, size, alpha }) => G.toColumnMajor(G.placement(vec(point), vec(normal), face, size, alpha)),
  rotationOf: ({ matrix }) => rotationMatrix(G.rotationOf(mat(matrix))),
  heading: ({ matrix, face, normal }) => G.heading(mat(matrix), face, vec(normal)),
  // the heading of a face attached unturned (α = 0), as the editor takes it to find an object's α
  zeroHeading: ({ face, normal, size }) => G.heading(G.placement(new THREE.Vector3(), vec(normal), face, size, 0), face,
    vec(normal)),
  // a point carried by a matrix read from 16 numbers, and the 16 numbers it is written back as
  columnMajor: ({ matrix, point }) => ({ point: vec(point).applyMatrix4(mat(matrix)).toArray(),
    values: G.toColumnMajor(mat(matrix)) }),
};

let input = "";
for await (const chunk of process.stdin) input += chunk;
const results = JSON.parse(input).map(([name, args]) => {
  if (!(name in CASES)) throw new Error(`no case ${name}`);
  return CASES[name](args);
});
process.stdout.write(JSON.stringify(results));
