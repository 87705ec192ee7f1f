// The editor's lighting, in one place: a sky/ground hemisphere and one sun. Untextured models and the room are
// shaded by a matte material that lights each vertex (Gouraud) with three.js's Lambert model — the same colours
// as MeshLambertMaterial on flat and gently curved surfaces at a fraction of the per-pixel cost, which is what
// decides the frame rate on software WebGL (SwiftShader) that many participants' laptops fall back to.
import * as THREE from "three";

const SKY = { colour: 0xffffff, ground: 0x8a7f70, intensity: 1.6 };
const SUN = { colour: 0xffffff, intensity: 1.4, position: [3, 6, 4] };

/** The scene lights, for the materials that use three.js's own lighting (textured models). */
export function addLights(scene) {
  scene.add(new THREE.HemisphereLight(SKY.colour, SKY.ground, SKY.intensity));
  const sun = new THREE.DirectionalLight(SUN.colour, SUN.intensity);
  sun.position.set(...SUN.position);
  scene.add(sun);
}

const vertexShader = `
uniform vec3 sky;
uniform vec3 ground;
uniform vec3 sun;
uniform vec3 sunDirection;
uniform vec3 albedo;
varying vec3 vFront;
varying vec3 vBack;
vec3 irradiance(vec3 n) {
  return mix(ground, sky, 0.5 * n.y + 0.5) + sun * max(dot(n, sunDirection), 0.0);
}
void main() {
  vec3 base = albedo;
#ifdef USE_COLOR
  base *= color;
#endif
  vec3 n = normalize(mat3(modelMatrix) * normal);
  vFront = base * irradiance(n) * 0.3183098861837907;  // Lambert BRDF: albedo / pi
  vBack = base * irradiance(-n) * 0.3183098861837907;
  gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}`;

const fragmentShader = `
varying vec3 vFront;
varying vec3 vBack;
void main() {
  gl_FragColor = vec4(gl_FrontFacing ? vFront : vBack, 1.0);
  #include <colorspace_fragment>
}`;

const materials = new Map();  // one material per (colour, vertexColors, side), shared by every mesh using it

/** A matte material lit per vertex by :data:`SKY` and :data:`SUN`: ``colour`` (hex, sRGB) times the vertex
 * colours when ``vertexColors``; a double-sided one lights back faces by their own side. Materials are shared:
 * consecutive draws with one material skip the uniform uploads. */
export function matteMaterial({ colour = 0xffffff, vertexColors = false, side = THREE.FrontSide } = {}) {
  const key = `${colour}/${vertexColors}/${side}`;
  if (!materials.has(key)) materials.set(key, createMatte(colour, vertexColors, side));
  return materials.get(key);
}

function createMatte(colour, vertexColors, side) {
  const scaled = (hex, k) => new THREE.Color(hex).multiplyScalar(k);  // linear working space, as three.js lights
  return new THREE.ShaderMaterial({
    vertexColors, side, vertexShader, fragmentShader,
    uniforms: {
      sky: { value: scaled(SKY.colour, SKY.intensity) },
      ground: { value: scaled(SKY.ground, SKY.intensity) },
      sun: { value: scaled(SUN.colour, SUN.intensity) },
      sunDirection: { value: new THREE.Vector3(...SUN.position).normalize() },
      albedo: { value: new THREE.Color(colour) },
    },
  });
}
