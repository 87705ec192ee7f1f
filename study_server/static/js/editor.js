// The scene editor: placing, replacing, moving along surfaces, turning about the support normal, deleting,
// undo/redo — every action logged as an event of the study's vocabulary.
import * as THREE from "three";
import * as G from "./geometry.js";

const CLICK_PX = 5;
// The rotation ring answers a press this close to it on screen (CSS pixels), however small the object or far the
// camera: its drawn tube alone can be thinner than a pixel.
const RING_HIT_PX = 8;
const RING_SAMPLES = 96;
const COARSE_DEG = 15;
const FINE_DEG = 1;

export class Editor {
  constructor({ viewer, models, scene, condition, trial, log, onChange = () => {}, strings }) {
    this.viewer = viewer;
    this.models = models;
    this.scene = scene;
    this.condition = condition;
    this.trial = trial;
    this.log = log;
    this.onChange = onChange;
    /** True once another page of the session took over: keys do nothing (the page takes no pointer input). */
    this.disabled = false;
    this.strings = strings;
    this.selected = null;
    this.undoStack = [];
    this.redoStack = [];
    this.drag = null;
    this.ring = this.makeRing();
    this.selectionBox = new THREE.BoxHelper(undefined, 0xf2b600);
    this.selectionBox.visible = false;
    viewer.scene.add(this.ring, this.selectionBox);
    for (const o of scene.objects.values()) if (o.parent !== null) this.showObject(o);
    const canvas = viewer.renderer.domElement;
    canvas.addEventListener("pointerdown", (e) => this.pointerDown(e));
    canvas.addEventListener("pointermove", (e) => this.pointerMove(e));
    canvas.addEventListener("pointerup", (e) => this.pointerUp(e));
    canvas.addEventListener("pointercancel", (e) => this.pointerUp(e));
    addEventListener("keydown", (e) => this.keyDown(e));
  }

  // --- objects -----------------------------------------------------------------------------------------
  showObject(o) {
    const info = this.models.info(o.modelId);
    const mesh = this.models.instance(o.modelId, o.size, info?.asset);
    mesh.userData.modelId = o.modelId;
    this.viewer.setObject(o.id, mesh, o.matrix);
    mesh.userData.ready.then(() => {
      if (this.viewer.meshes.get(o.id) !== mesh) return;
      this.viewer.setObject(o.id, mesh, this.scene.objects.get(o.id)?.matrix ?? o.matrix);
      this.updateHandles();
    });
  }

  sync(ids) {
    for (const id of ids) {
      const o = this.scene.objects.get(id);
      if (!o) { this.viewer.removeObject(id); if (this.selected === id) this.select(null, false); continue; }
      const mesh = this.viewer.meshes.get(id);
      if (mesh && mesh.userData.modelId === o.modelId) this.viewer.moveObject(id, o.matrix);
      else this.showObject(o);
    }
    this.updateHandles();
    this.onChange();
  }

  /** Place a model: its ``face`` on the surface at ``point`` (on ``parent``), turned by the rotation ``q``. */
  record({ id, modelId, category, size, parent, point, normal, face, q }) {
    const parentObject = this.scene.objects.get(parent);
    const matrix = G.poseMatrix(point, q, face, size);
    return { id, modelId, category, size: size.slice(), matrix, parent, face,
      surfaceType: G.surfaceType(parentObject.matrix, parentObject.size, point, normal),
      contactPoint: point.toArray(), contactNormal: normal.toArray() };
  }

  insert(spec, how) {
    const id = this.scene.newId(spec.category);
    const before = this.scene.snapshot([id]);
    this.scene.objects.set(id, this.record({ ...spec, id }));
    this.commit("insert", before, [id]);
    this.log("insert", { object: id, model: spec.modelId, category: spec.category, rank: how.rank ?? null,
      source: how.source, list_id: how.listId ?? null, objects: this.scene.states([id]) });
    this.select(id, false);
    return id;
  }

  replace(oldId, spec, how) {
    const old = this.scene.objects.get(oldId);
    if (!old) return this.insert(spec, how);
    const id = this.scene.newId(spec.category);
    const moved = this.scene.children(oldId).map((c) => c.id);
    const before = this.scene.snapshot([oldId, id, ...moved]);
    this.scene.objects.delete(oldId);
    this.scene.objects.set(id, this.record({ ...spec, id }));
    for (const cid of moved) this.scene.objects.get(cid).parent = id;
    this.commit("replace", before, [oldId, id, ...moved]);
    this.log("replace", { object: id, replaces: oldId, model: spec.modelId, category: spec.category,
      rank: how.rank ?? null, source: how.source, list_id: how.listId ?? null,
      objects: this.scene.states([oldId, id, ...moved]) });
    this.select(id, false);
    return id;
  }

  deleteSelected() {
    const id = this.selected;
    if (!id) return;
    const gone = [id, ...this.scene.descendants(id).map((o) => o.id)];
    const before = this.scene.snapshot(gone);
    for (const g of gone) this.scene.objects.delete(g);
    this.select(null, false);
    this.commit("delete", before, gone);
    this.log("delete", { object: id, objects: this.scene.states(gone) });
  }

  /** Apply a new matrix to an object and carry everything resting on it along. */
  transformTree(id, matrix) {
    const o = this.scene.objects.get(id);
    const delta = matrix.clone().multiply(o.matrix.clone().invert());
    const touched = [id];
    o.matrix = matrix;
    for (const d of this.scene.descendants(id)) {
      d.matrix = delta.clone().multiply(d.matrix);
      if (d.contactPoint) d.contactPoint = new THREE.Vector3(...d.contactPoint).applyMatrix4(delta).toArray();
      if (d.contactNormal) d.contactNormal = new THREE.Vector3(...d.contactNormal).transformDirection(delta).toArray();
      touched.push(d.id);
    }
    return touched;
  }

  alphaOf(o) {
    const n = new THREE.Vector3(...o.contactNormal);
    const zero = G.heading(G.placement(new THREE.Vector3(), n, o.face, o.size, 0), o.face, n);
    return G.heading(o.matrix, o.face, n) - zero;
  }

  rotate(id, radians) {
    const o = this.scene.objects.get(id);
    if (!o || !o.contactNormal) return [];
    const n = new THREE.Vector3(...o.contactNormal);
    const anchor = new THREE.Vector3(...o.contactPoint);
    return this.transformTree(id, G.placement(anchor, n, o.face, o.size, this.alphaOf(o) + radians));
  }

  /** Move onto the surface under the pointer (same kind of surface: walls stay on walls). */
  moveTo(id, hit) {
    const o = this.scene.objects.get(id);
    const want = G.surfaceDirection(new THREE.Vector3(...o.contactNormal));
    if (G.surfaceDirection(hit.normal) !== want) return null;
    const alpha = this.alphaOf(o);
    const matrix = G.placement(hit.point, hit.normal, o.face, o.size, alpha);
    const touched = this.transformTree(id, matrix);
    const parent = this.scene.objects.get(hit.objectId);
    o.parent = hit.objectId;
    o.contactPoint = hit.point.toArray();
    o.contactNormal = hit.normal.toArray();
    o.surfaceType = G.surfaceType(parent.matrix, parent.size, hit.point, hit.normal);
    return touched;
  }

  // --- undo ----------------------------------------------------------------------------------------------
  commit(action, before, ids) {
    this.undoStack.push({ action, before, after: this.scene.snapshot(ids) });
    this.redoStack = [];
    this.sync(ids);
  }

  undo() {
    const step = this.undoStack.pop();
    if (!step) return;
    this.scene.restore(step.before);
    this.redoStack.push(step);
    this.sync([...step.before.keys()]);
    this.log("undo", { action: step.action, objects: this.scene.states([...step.before.keys()]) });
  }

  redo() {
    const step = this.redoStack.pop();
    if (!step) return;
    this.scene.restore(step.after);
    this.undoStack.push(step);
    this.sync([...step.after.keys()]);
    this.log("redo", { action: step.action, objects: this.scene.states([...step.after.keys()]) });
  }

  // --- selection and handles ------------------------------------------------------------------------------
  select(id, log = true) {
    if (this.selected === id) return;
    this.selected = id;
    if (log) this.log("select", { object: id });
    this.updateHandles();
    this.onChange();
  }

  makeRing() {
    const ring = new THREE.Mesh(new THREE.TorusGeometry(1, 0.035, 8, 48),
      new THREE.MeshBasicMaterial({ color: 0x2f6fde, transparent: true, opacity: 0.85, depthTest: false }));
    ring.renderOrder = 10;
    ring.visible = false;
    ring.userData.handle = "rotate";
    return ring;
  }

  updateHandles() {
    this.viewer.invalidate();
    const o = this.selected && this.scene.objects.get(this.selected);
    const mesh = o && this.viewer.meshes.get(o.id);
    this.ring.visible = !!(o && o.contactNormal);
    this.selectionBox.visible = !!mesh;
    if (!o || !mesh) return;
    this.selectionBox.setFromObject(mesh);
    if (!o.contactNormal) return;
    const n = new THREE.Vector3(...o.contactNormal).normalize();
    const box = this.scene.worldBox(o);
    const size = box.getSize(new THREE.Vector3());
    const flat = size.clone().sub(n.clone().multiply(size).multiply(n.clone()));  // extent within the plane
    const radius = Math.max(0.25, Math.hypot(flat.x, flat.y, flat.z) * 0.55);
    this.ring.scale.setScalar(radius);
    this.ring.position.copy(new THREE.Vector3(...o.contactPoint)).addScaledVector(n, 0.01);
    this.ring.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), n);
  }

  // --- pointer and keys ---------------------------------------------------------------------------------
  pointerDown(e) {
    if (e.button !== 0) return;
    this.press = { x: e.clientX, y: e.clientY, t: performance.now(), shift: e.shiftKey };
    const hit = this.viewer.pick(e.clientX, e.clientY, { extra: this.ring.visible ? [this.ring] : [] });
    // the ring's hit area reaches beyond its tube, but never over an object under the pointer
    if (hit?.handle === "rotate" || ((!hit || hit.room) && !e.shiftKey && this.nearRing(e.clientX, e.clientY))) {
      this.startRotate(e, hit);
    } else if (hit && !hit.room && hit.objectId && !e.shiftKey && !this.placingModel) {
      this.drag = { id: hit.objectId, start: { x: e.clientX, y: e.clientY }, moved: false, distance: 0,
        before: null, last: new THREE.Vector3(...this.scene.objects.get(hit.objectId).contactPoint) };
      this.viewer.controls.enabled = false;
      this.viewer.renderer.domElement.setPointerCapture(e.pointerId);
    }
  }

  /** Whether a pixel is within RING_HIT_PX of the visible ring's circle as drawn on screen. */
  nearRing(x, y) {
    if (!this.ring.visible) return false;
    const n = new THREE.Vector3(0, 0, 1).applyQuaternion(this.ring.quaternion);
    const u = new THREE.Vector3(1, 0, 0).applyQuaternion(this.ring.quaternion);
    const v = new THREE.Vector3().crossVectors(n, u);
    const r = this.ring.scale.x;
    const point = (k) => {
      const a = (2 * Math.PI * k) / RING_SAMPLES;
      const p = this.ring.position.clone().addScaledVector(u, r * Math.cos(a)).addScaledVector(v, r * Math.sin(a));
      return this.viewer.worldToPixel(p.x, p.y, p.z);
    };
    let [ax, ay] = point(0);
    for (let k = 1; k <= RING_SAMPLES; k += 1) {
      const [bx, by] = point(k);
      const dx = bx - ax;
      const dy = by - ay;
      const along = Math.max(0, Math.min(1, ((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy || 1)));
      if (Math.hypot(x - ax - along * dx, y - ay - along * dy) <= RING_HIT_PX) return true;
      [ax, ay] = [bx, by];
    }
    return false;
  }

  startRotate(e, hit) {
    const o = this.scene.objects.get(this.selected);
    this.turn = { id: o.id, angle: 0, before: this.scene.snapshot([o.id, ...this.scene.descendants(o.id).map((d) => d.id)]),
      last: this.angleAt(e, o) };
    this.viewer.controls.enabled = false;
    this.viewer.renderer.domElement.setPointerCapture(e.pointerId);
    this.log("rotate_start", { object: o.id });
  }

  /** Angle (radians, about the support normal) of the pointer around the object's anchor. */
  angleAt(e, o) {
    const n = new THREE.Vector3(...o.contactNormal).normalize();
    const anchor = new THREE.Vector3(...o.contactPoint);
    const rect = this.viewer.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((e.clientX - rect.left) / rect.width) * 2 - 1, -((e.clientY - rect.top) / rect.height) * 2 + 1);
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.viewer.camera);
    const p = ray.ray.intersectPlane(new THREE.Plane().setFromNormalAndCoplanarPoint(n, anchor), new THREE.Vector3());
    if (!p) return null;
    const v = p.sub(anchor);
    const zero = G.isHorizontal(n) ? new THREE.Vector3(0, 0, 1) : new THREE.Vector3(0, 1, 0);
    zero.addScaledVector(n, -zero.dot(n)).normalize();
    return Math.atan2(new THREE.Vector3().crossVectors(zero, v).dot(n), zero.dot(v));
  }

  pointerMove(e) {
    if (this.turn) {
      const o = this.scene.objects.get(this.turn.id);
      const a = this.angleAt(e, o);
      if (a === null || this.turn.last === null) { this.turn.last = a; return; }
      let d = a - this.turn.last;
      d = Math.atan2(Math.sin(d), Math.cos(d));
      this.turn.last = a;
      this.turn.angle += d;
      this.syncQuiet(this.rotate(o.id, d));
      return;
    }
    if (!this.drag) return;
    const d = this.drag;
    if (!d.moved && Math.hypot(e.clientX - d.start.x, e.clientY - d.start.y) < CLICK_PX) return;
    if (!d.moved) {
      d.moved = true;
      d.before = this.scene.snapshot([d.id, ...this.scene.descendants(d.id).map((o) => o.id)]);
      this.select(d.id);
      this.log("move_start", { object: d.id });
    }
    const exclude = new Set([d.id, ...this.scene.descendants(d.id).map((o) => o.id)]);
    const hit = this.viewer.pick(e.clientX, e.clientY, { exclude });
    if (!hit) return;
    const touched = this.moveTo(d.id, hit);
    if (touched) {
      d.distance += hit.point.distanceTo(d.last);
      d.last = hit.point.clone();
      this.syncQuiet(touched);
    }
  }

  syncQuiet(ids) {
    for (const id of ids) this.viewer.moveObject(id, this.scene.objects.get(id).matrix);
    this.updateHandles();
  }

  pointerUp(e) {
    this.viewer.controls.enabled = true;
    if (this.turn) {
      const t = this.turn;
      this.turn = null;
      const ids = [...t.before.keys()];
      this.undoStack.push({ action: "rotate", before: t.before, after: this.scene.snapshot(ids) });
      this.redoStack = [];
      this.sync(ids);
      this.log("rotate_end", { object: t.id, angle: THREE.MathUtils.radToDeg(t.angle), objects: this.scene.states(ids) });
      return;
    }
    const d = this.drag;
    this.drag = null;
    if (d && d.moved) {
      const ids = [...d.before.keys()];
      this.undoStack.push({ action: "move", before: d.before, after: this.scene.snapshot(ids) });
      this.redoStack = [];
      this.sync(ids);
      const o = this.scene.objects.get(d.id);
      this.log("move_end", { object: d.id, distance: d.distance, parent: o.parent, objects: this.scene.states(ids) });
      return;
    }
    const p = this.press;
    if (p && Math.hypot(e.clientX - p.x, e.clientY - p.y) < CLICK_PX) this.click(e, p.shift);
  }

  click(e, shift) {
    const hit = this.viewer.pick(e.clientX, e.clientY);
    this.onClick?.(e, hit, shift);
  }

  keyDown(e) {
    if (this.disabled) return;  // another page of the session took over
    const tag = (e.target && e.target.tagName) || "";
    if (tag === "INPUT" || tag === "TEXTAREA") return;
    const key = e.key.toLowerCase();
    if ((e.ctrlKey || e.metaKey) && key === "z") { e.preventDefault(); if (e.shiftKey) this.redo(); else this.undo(); return; }
    if ((e.ctrlKey || e.metaKey) && key === "y") { e.preventDefault(); this.redo(); return; }
    if (!this.selected) return;
    if (key === "delete" || key === "backspace") { e.preventDefault(); this.deleteSelected(); return; }
    if (key === "escape") { this.select(null); return; }
    if (key === "q" || key === "e") {
      e.preventDefault();
      const step = THREE.MathUtils.degToRad((e.shiftKey ? FINE_DEG : COARSE_DEG) * (key === "q" ? 1 : -1));
      const id = this.selected;
      const ids = [id, ...this.scene.descendants(id).map((o) => o.id)];
      const before = this.scene.snapshot(ids);
      this.log("rotate_start", { object: id });
      this.rotate(id, step);
      this.undoStack.push({ action: "rotate", before, after: this.scene.snapshot(ids) });
      this.redoStack = [];
      this.sync(ids);
      this.log("rotate_end", { object: id, angle: THREE.MathUtils.radToDeg(step), objects: this.scene.states(ids) });
    }
  }
}
