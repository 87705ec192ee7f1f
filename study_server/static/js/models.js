// Model assets: GLB files loaded once each and cloned per object; a grey box stands in while a model loads,
// and a model that fails to load is reported so the page can offer a retry instead of a blank canvas.
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { mergeGeometries } from "three/addons/utils/BufferGeometryUtils.js";
import { matteMaterial } from "./shading.js";

const loader = new GLTFLoader();

/** At most two draw calls per model: untextured parts are merged, with vertex colours and matte shading lit per
 * vertex (shading.js), into one mesh of the closed parts (back faces culled: the asset pipeline marks a part single-sided
 * only when it is a closed, outward-wound volume) and one of the open, double-sided parts. Several times cheaper
 * than separate PBR parts on software WebGL, which is what many participants' laptops fall back to. Textured
 * models keep their parts, shaded matte. */
function simplify(scene) {
  scene.updateMatrixWorld(true);
  const parts = [];
  let textured = false;
  scene.traverse((node) => {
    if (!node.isMesh) return;
    parts.push(node);
    const materials = Array.isArray(node.material) ? node.material : [node.material];
    if (materials.some((m) => m.map) || materials.length > 1) textured = true;
  });
  if (textured || !parts.length) {
    for (const node of parts) {
      const m = node.material;
      node.material = new THREE.MeshLambertMaterial({ color: m.color, map: m.map ?? null, side: m.side });
    }
    return scene;
  }
  const group = new THREE.Group();
  for (const side of [THREE.FrontSide, THREE.DoubleSide]) {
    const same = parts.filter((node) => (node.material.side === THREE.FrontSide) === (side === THREE.FrontSide));
    if (!same.length) continue;
    group.add(new THREE.Mesh(mergeGeometries(same.map(colouredGeometry)),
      matteMaterial({ vertexColors: true, side })));
  }
  return group;
}

/** A part's triangles in model coordinates, non-indexed, with its material colour as a vertex colour. */
function colouredGeometry(node) {
  const g = new THREE.BufferGeometry();
  const source = node.geometry.index ? node.geometry.toNonIndexed() : node.geometry;
  g.setAttribute("position", source.getAttribute("position").clone());
  if (source.getAttribute("normal")) g.setAttribute("normal", source.getAttribute("normal").clone());
  else g.computeVertexNormals();
  const n = g.getAttribute("position").count;
  const colour = new THREE.Color(node.material.color);
  const colours = new Float32Array(n * 3);
  for (let i = 0; i < n; i += 1) colours.set([colour.r, colour.g, colour.b], i * 3);
  g.setAttribute("color", new THREE.BufferAttribute(colours, 3));
  g.applyMatrix4(node.matrixWorld);
  return g;
}

export class ModelLibrary {
  constructor(models, { onError = () => {} } = {}) {
    this.byId = new Map(models.map((m) => [m.id, m]));
    this.cache = new Map();  // url → Promise<THREE.Object3D>
    this.onError = onError;
    this.failed = new Set();
  }

  info(modelId) { return this.byId.get(modelId); }

  load(url) {
    if (!this.cache.has(url)) {
      const p = loader.loadAsync(url).then((gltf) => simplify(gltf.scene)).catch((error) => {
        this.cache.delete(url);  // a retry loads again
        this.failed.add(url);
        this.onError(url, error);
        throw error;
      });
      this.cache.set(url, p);
    }
    return this.cache.get(url);
  }

  /** An object for ``modelId``: a placeholder box now, the real mesh swapped in when it has loaded. */
  instance(modelId, size, assetUrl) {
    const holder = new THREE.Group();
    const placeholder = new THREE.Mesh(new THREE.BoxGeometry(size[0], size[1], size[2]),
      new THREE.MeshLambertMaterial({ color: 0xb8c0cc, transparent: true, opacity: 0.55 }));
    placeholder.position.y = size[1] / 2;
    placeholder.userData.placeholder = true;
    holder.add(placeholder);
    const url = assetUrl || this.byId.get(modelId)?.asset;
    holder.userData.ready = url ? this.load(url).then((scene) => {
      const copy = scene.clone(true);
      copy.traverse((n) => { if (n.isMesh) { n.castShadow = true; n.receiveShadow = true; } });
      holder.remove(placeholder);
      holder.add(copy);
      return holder;
    }).catch(() => holder) : Promise.resolve(holder);
    return holder;
  }

  retry() {
    const urls = [...this.failed];
    this.failed.clear();
    return urls;
  }
}
