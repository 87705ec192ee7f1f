// The editor's scene: objects with their canonical → world matrices and support tree, convertible to and
// from the native scene JSON (scenesuggest/scenes/scene_json.py), with snapshots for undo and reloads.
import * as THREE from "three";
import { fromColumnMajor, toColumnMajor } from "./geometry.js";

export class SceneModel {
  constructor(doc) {
    this.id = doc.id || "editor";
    this.sceneType = doc.scene_type || "Room";
    this.source = doc.source || "editor";
    this.objects = new Map();
    for (const o of doc.objects || []) this.objects.set(o.id, SceneModel.fromJSON(o));
    this.counter = 0;
  }

  static fromJSON(o) {
    return { id: o.id, modelId: o.model_id, category: o.category, size: o.size.slice(), matrix: fromColumnMajor(o.transform),
      parent: o.parent ?? null, surfaceType: o.surface_type ?? null, face: o.attachment_face ?? null,
      contactPoint: o.contact_point ? o.contact_point.slice() : null, contactNormal: o.contact_normal ? o.contact_normal.slice() : null };
  }

  static toJSON(o) {
    return { id: o.id, model_id: o.modelId, category: o.category, size: o.size.slice(), transform: toColumnMajor(o.matrix),
      parent: o.parent, surface_type: o.surfaceType, attachment_face: o.face, contact_point: o.contactPoint,
      contact_normal: o.contactNormal };
  }

  /** An object's state as the scene-changing events carry it (scenesuggest/contract/events.py OBJECT_STATE): the object
   * as a scene file lists it, numbers to 0.1 µm (events stay small; a replay matches the scene within 1 µm). */
  static stateJSON(o) {
    const r = (x) => Math.round(x * 1e7) / 1e7;
    const v = (a) => (a ? a.map(r) : null);
    const j = SceneModel.toJSON(o);
    return { ...j, size: v(j.size), transform: v(j.transform), contact_point: v(j.contact_point),
      contact_normal: v(j.contact_normal) };
  }

  /** The states after a change of the objects ``ids`` (an object no longer there: ``{id, removed: true}``). */
  states(ids) {
    return [...new Set(ids)].map((id) => {
      const o = this.objects.get(id);
      return o ? SceneModel.stateJSON(o) : { id, removed: true };
    });
  }

  toJSON() {
    return { format: "scenesuggest-scene", version: 1, id: this.id, scene_type: this.sceneType, source: this.source,
      objects: [...this.objects.values()].map(SceneModel.toJSON) };
  }

  /** The objects in the API's {"objects": [...]} shape. */
  objectsJSON() { return { objects: [...this.objects.values()].map(SceneModel.toJSON) }; }

  get root() { return [...this.objects.values()].find((o) => o.parent === null); }

  newId(category) {
    let id;
    do { this.counter += 1; id = `${category.toLowerCase()}-${this.counter}`; } while (this.objects.has(id));
    return id;
  }

  children(id) { return [...this.objects.values()].filter((o) => o.parent === id); }

  descendants(id) {
    const out = [];
    const stack = [id];
    while (stack.length) {
      for (const c of this.children(stack.pop())) { out.push(c); stack.push(c.id); }
    }
    return out;
  }

  worldBox(o) {
    const box = new THREE.Box3(new THREE.Vector3(-o.size[0] / 2, 0, -o.size[2] / 2), new THREE.Vector3(o.size[0] / 2, o.size[1], o.size[2] / 2));
    return box.applyMatrix4(o.matrix);
  }

  /** A deep copy of some objects' state (for undo). */
  snapshot(ids) {
    const out = new Map();
    for (const id of ids) {
      const o = this.objects.get(id);
      out.set(id, o ? { ...o, size: o.size.slice(), matrix: o.matrix.clone(),
        contactPoint: o.contactPoint?.slice() ?? null, contactNormal: o.contactNormal?.slice() ?? null } : null);
    }
    return out;
  }

  restore(snapshot) {
    for (const [id, o] of snapshot) {
      if (o === null) this.objects.delete(id);
      else this.objects.set(id, { ...o, size: o.size.slice(), matrix: o.matrix.clone() });
    }
  }
}
