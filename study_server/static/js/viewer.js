// The 3D view: the editor's scene on its room, an orbit camera, the target scene as an inset bottom-left
// (enlarged on hover), picking, and world → pixel conversion for tests.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { addLights, matteMaterial } from "./shading.js";

const WALL_COLOUR = 0xe9e4dc;
// Adaptive resolution: while the camera moves and frames come slower than SLOW_FRAME_MS (smoothed), the view is
// drawn at MOTION_SCALE of its pixel ratio; it is drawn sharp again once the camera has been still SETTLE_MS.
const SLOW_FRAME_MS = 30;
const MOTION_SCALE = 0.7;
const SETTLE_MS = 150;
const FLOOR_COLOUR = 0xc9a77c;

/** Floor and four walls of a room box, walls visible from inside only (so the camera sees in). */
function roomMesh(box, objectId) {
  const group = new THREE.Group();
  const size = box.getSize(new THREE.Vector3());
  const centre = box.getCenter(new THREE.Vector3());
  const floor = new THREE.Mesh(new THREE.PlaneGeometry(size.x, size.z), matteMaterial({ colour: FLOOR_COLOUR }));
  floor.rotation.x = -Math.PI / 2;
  floor.position.set(centre.x, box.min.y, centre.z);
  floor.userData = { objectId, room: true };
  group.add(floor);
  const wallMaterial = matteMaterial({ colour: WALL_COLOUR, side: THREE.FrontSide });
  const walls = [
    [size.x, [centre.x, box.min.z], 0], [size.x, [centre.x, box.max.z], Math.PI],
    [size.z, [box.min.x, centre.z], Math.PI / 2], [size.z, [box.max.x, centre.z], -Math.PI / 2],
  ];
  for (const [width, [x, z], turn] of walls) {
    const wall = new THREE.Mesh(new THREE.PlaneGeometry(width, size.y), wallMaterial);
    wall.position.set(x, box.min.y + size.y / 2, z);
    wall.rotation.y = turn;
    wall.userData = { objectId, room: true };
    group.add(wall);
  }
  return group;
}

export class Viewer {
  constructor(container, { onCameraChange = () => {} } = {}) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: false });
    this.pixelRatio = Math.min(window.devicePixelRatio || 1, 2);
    this.renderer.setPixelRatio(this.pixelRatio);
    this.adaptive = true;  // adaptive resolution while the camera moves (see SLOW_FRAME_MS)
    this.slowFrameMs = SLOW_FRAME_MS;
    this.scale = 1;
    this.frameMs = 0;
    this.movedAt = -Infinity;
    this.lowestScale = 1;
    this.renderer.setClearColor(0xf4f6f9);
    this.renderer.domElement.className = "view";
    container.prepend(this.renderer.domElement);
    this.scene = new THREE.Scene();
    addLights(this.scene);
    this.camera = new THREE.PerspectiveCamera(50, 1, 0.05, 100);
    this.controls = null;  // created after the editor's own pointer handlers (they run first)
    this.onCameraChange = onCameraChange;
    this.meshes = new Map();  // object id → THREE.Object3D
    this.pickables = [];
    this.target = null;
    this.dirty = true;
    this.raycaster = new THREE.Raycaster();
    this.frames = 0;
    this.home = { position: new THREE.Vector3(4, 3.5, 5), target: new THREE.Vector3() };
    new ResizeObserver(() => this.resize()).observe(container);
  }

  startControls() {
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.enableDamping = false;
    this.controls.maxPolarAngle = Math.PI * 0.495;
    this.controls.minDistance = 0.5;
    this.controls.maxDistance = 25;
    this.controls.screenSpacePanning = true;
    this.controls.addEventListener("change", () => { this.movedAt = performance.now(); this.invalidate(); });
    this.controls.addEventListener("start", () => {
      this.gestureStart = this.camera.position.distanceTo(this.controls.target);
      this.gestureFrom = this.camera.position.clone();
    });
    this.controls.addEventListener("end", () => {  // a click that did not move the camera is not a camera action
      if (this.gestureFrom && this.camera.position.distanceTo(this.gestureFrom) > 1e-6) {
        this.onCameraChange(this.camera.position.distanceTo(this.controls.target));
      }
    });
    this.resetView();
  }

  /** Frame the room from the front, a little above. */
  setRoom(model) {
    if (this.room) this.scene.remove(this.room);
    const root = model.root;
    const box = model.worldBox(root);
    this.room = roomMesh(box, root.id);
    this.scene.add(this.room);
    this.roomBox = box;
    this.refreshPickables();
    this.invalidate();
    const size = box.getSize(new THREE.Vector3());
    const centre = box.getCenter(new THREE.Vector3());
    this.home.target.set(centre.x, box.min.y + 0.6, centre.z);
    this.home.position.set(centre.x + size.x * 0.35, box.min.y + Math.max(2.6, size.y * 1.1), centre.z + size.z * 0.95 + 1.2);
    this.resetView();
  }

  resetView() {
    this.camera.position.copy(this.home.position);
    if (this.controls) {
      this.controls.target.copy(this.home.target);
      this.controls.update();
    } else {
      this.camera.lookAt(this.home.target);
    }
  }

  /** Ask for a new frame (the view renders only when something changed). */
  invalidate() { this.dirty = true; }

  setObject(id, object3d, matrix) {
    const old = this.meshes.get(id);
    if (old && old !== object3d) this.scene.remove(old);
    object3d.matrixAutoUpdate = false;
    object3d.matrix.copy(matrix);
    object3d.matrixWorldNeedsUpdate = true;
    object3d.traverse((n) => { n.userData.objectId = id; });
    if (!object3d.parent) this.scene.add(object3d);
    this.meshes.set(id, object3d);
    this.refreshPickables();
    this.invalidate();
  }

  moveObject(id, matrix) {
    const m = this.meshes.get(id);
    if (m) { m.matrix.copy(matrix); m.matrixWorldNeedsUpdate = true; }
    this.invalidate();
  }

  removeObject(id) {
    const m = this.meshes.get(id);
    if (m) this.scene.remove(m);
    this.meshes.delete(id);
    this.refreshPickables();
    this.invalidate();
  }

  refreshPickables() {
    this.pickables = [...this.meshes.values()];
    if (this.room) this.pickables.push(this.room);
  }

  /** The surface under a pixel: {objectId, point, normal (world, facing the camera), room} or null. */
  pick(clientX, clientY, { exclude = new Set(), extra = [] } = {}) {
    const rect = this.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
    this.raycaster.setFromCamera(ndc, this.camera);
    const hits = this.raycaster.intersectObjects([...extra, ...this.pickables], true);
    for (const hit of hits) {
      let node = hit.object;
      if (!node.visible) continue;
      const id = node.userData.objectId;
      if (node.userData.handle) return { handle: node.userData.handle, point: hit.point };
      if (id === undefined || exclude.has(id)) continue;
      const normal = hit.face.normal.clone().transformDirection(node.matrixWorld);
      if (normal.dot(this.raycaster.ray.direction) > 0) normal.negate();
      while (node && !node.userData.room && node.parent && node.parent !== this.scene) node = node.parent;
      return { objectId: id, point: hit.point.clone(), normal, room: !!hit.object.userData.room };
    }
    return null;
  }

  /** Page pixel of a world point (for tests clicking real pixels). */
  worldToPixel(x, y, z) {
    const v = new THREE.Vector3(x, y, z).project(this.camera);
    const rect = this.renderer.domElement.getBoundingClientRect();
    return [rect.left + (v.x + 1) / 2 * rect.width, rect.top + (1 - v.y) / 2 * rect.height];
  }

  /** The target scene, in its own small view (rendered when it changes, not every frame). */
  setTarget(model, instances, element) {
    if (this.target) this.target.dispose();
    this.target = new TargetView(model, instances, element);
  }

  resize() {
    const { clientWidth: w, clientHeight: h } = this.container;
    if (!w || !h) return;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.invalidate();
  }

  render() {
    this.renderer.render(this.scene, this.camera);
    if (this.frames === 0) this.firstFrameAt = performance.now();
    this.frames += 1;
  }

  /** Draw at ``scale`` × the device pixel ratio (1: sharp). */
  setScale(scale) {
    if (scale === this.scale) return;
    this.scale = scale;
    this.lowestScale = Math.min(this.lowestScale, scale);
    this.renderer.setPixelRatio(this.pixelRatio * scale);
    this.invalidate();
  }

  loop(beforeFrame = () => {}) {
    let last = null;  // when the previous frame was drawn while the camera moved
    const tick = (now) => {
      const moving = now - this.movedAt < SETTLE_MS;
      if (!moving) {
        last = null;
        this.frameMs = 0;
        this.setScale(1);
      }
      if (this.dirty) {
        this.dirty = false;
        if (moving) {
          if (last !== null) this.frameMs = this.frameMs ? 0.8 * this.frameMs + 0.2 * (now - last) : now - last;
          if (this.adaptive && this.frameMs > this.slowFrameMs) this.setScale(MOTION_SCALE);
          last = now;
        }
        beforeFrame();
        this.render();
      }
      requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
  }
}

/** A scene's objects on their room with a camera that frames them from the front, a little above (the target
 * inset and the target image); ``ready`` resolves when every model has loaded. */
function framedScene(model, instances) {
  const scene = new THREE.Scene();
  addLights(scene);
  scene.add(roomMesh(model.worldBox(model.root), model.root.id));
  const camera = new THREE.PerspectiveCamera(40, 1, 0.05, 100);
  const box = new THREE.Box3();
  const ready = [];
  for (const o of model.objects.values()) {
    if (o.parent === null) continue;
    const mesh = instances(o);
    mesh.matrixAutoUpdate = false;
    mesh.matrix.copy(o.matrix);
    scene.add(mesh);
    box.union(model.worldBox(o));
    ready.push(mesh.userData.ready);
  }
  if (box.isEmpty()) box.copy(model.worldBox(model.root));
  const centre = box.getCenter(new THREE.Vector3());
  const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 0.6);
  camera.position.set(centre.x + radius * 1.1, centre.y + radius * 1.3, centre.z + radius * 2.1);
  camera.lookAt(centre);
  return { scene, camera, ready: Promise.all(ready) };
}

class TargetView {
  constructor(model, instances, element) {
    this.element = element;
    this.renderer = new THREE.WebGLRenderer({ antialias: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.renderer.setClearColor(0xffffff);
    element.append(this.renderer.domElement);
    const { scene, camera, ready } = framedScene(model, instances);
    this.scene = scene;
    this.camera = camera;
    this.objects = model.objects.size - 1;
    this.ready = ready.then(() => this.render());
    this.observer = new ResizeObserver(() => this.render());
    this.observer.observe(element);
    this.render();
  }

  dispose() {
    this.observer.disconnect();
    this.renderer.domElement.remove();
    this.renderer.dispose();
  }

  render() {
    const { clientWidth: w, clientHeight: h } = this.element;
    if (!w || !h) return;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.renderer.render(this.scene, this.camera);
  }
}

/** A PNG data URL of ``model`` framed as the target inset frames it, ``width`` × ``height`` pixels, once every
 * model has loaded (the target image of a study's scene). */
export async function renderImage(model, instances, width = 1280, height = 960) {
  const { scene, camera, ready } = framedScene(model, instances);
  await ready;
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  try {
    renderer.setPixelRatio(1);
    renderer.setSize(width, height, false);
    renderer.setClearColor(0xffffff);
    camera.aspect = width / height;
    camera.updateProjectionMatrix();
    renderer.render(scene, camera);
    return renderer.domElement.toDataURL("image/png");
  } finally {
    renderer.dispose();
  }
}
