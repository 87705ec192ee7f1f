// The trial page: loads the scenes and models, wires the editor to the study's condition, logs every
// interaction through the outbox, keeps the scene across reloads, and finishes the trial.
import * as THREE from "three";
import { Editor } from "./editor.js";
import * as G from "./geometry.js";
import { ModelLibrary } from "./models.js";
import { Outbox } from "./outbox.js";
import { ModelListPanel, SuggestionPanel } from "./panels.js";
import { SceneModel } from "./scene-model.js";
import { renderImage, Viewer } from "./viewer.js";

const boot = JSON.parse(document.getElementById("boot").textContent);
const strings = JSON.parse(document.getElementById("strings").textContent);
const trial = boot.trial;
const $ = (id) => document.getElementById(id);
const banner = $("banner");
const testLog = [];

function say(text, { action = null, onAction = null } = {}) {
  banner.replaceChildren(document.createTextNode(text));
  if (action) {
    const b = document.createElement("button");
    b.type = "button";
    b.textContent = action;
    b.addEventListener("click", onAction);
    banner.append(" ", b);
  }
  banner.hidden = !text;
}

const outbox = new Outbox({ api: boot.api, token: boot.token, pageId: boot.page_id, study: boot.study,
  onStatus: (s) => {
    if (s === "offline") say(strings.offline);
    else if (s === "ended") say(strings.ended, { action: strings.continue, onAction: () => location.assign(boot.next) });
    else if (banner.dataset.kind !== "model") say("");
    banner.dataset.state = s;
  } });
const api = (path, options = {}) => fetch(`${boot.api}${path}`, { ...options,
  headers: { "Content-Type": "application/json", Authorization: `Bearer ${boot.token}`, ...(options.headers || {}) } });
const log = (type, payload = {}) => {
  const seq = outbox.log(type, payload, trial.index);
  testLog.push({ seq, type, payload });
  return seq;
};
const sceneKey = `scenesuggest-scene-${boot.study}-${boot.token.slice(-12)}-${trial.index}`;

async function json(path) {
  for (let attempt = 0; ; attempt += 1) {
    try {
      const r = await api(path);
      if (r.ok) return await r.json();
    } catch (e) { /* offline: retry */ }
    say(strings.offline);
    await new Promise((res) => setTimeout(res, Math.min(10000, 500 * 2 ** attempt)));
  }
}

function logInputs(viewer) {
  const canvas = viewer.renderer.domElement;
  const kinds = new Set();
  let button = 0;
  canvas.addEventListener("pointerdown", (e) => {
    button = e.button;
    if (!kinds.has(e.pointerType)) { kinds.add(e.pointerType); log("pointer", { kind: e.pointerType }); }
  });
  viewer.onCameraChange = (distance) => {
    const zoomed = Math.abs(distance - (viewer.gestureStart ?? distance)) > 1e-3;
    log("camera", { action: zoomed ? "zoom" : button === 2 ? "pan" : "orbit", distance });
  };
  let wheel = null;
  canvas.addEventListener("wheel", (e) => {
    if (!wheel) {
      wheel = { dx: 0, dy: 0, mode: e.deltaMode };
      setTimeout(() => { log("wheel", wheel); wheel = null; }, 300);
    }
    wheel.dx += e.deltaX;
    wheel.dy += e.deltaY;
  }, { passive: true });
  addEventListener("focus", () => log("focus", { state: "focus" }));
  addEventListener("blur", () => log("focus", { state: "blur" }));
  document.addEventListener("visibilitychange", () => log("visibility", { state: document.visibilityState }));
  let resizeTimer = null;
  addEventListener("resize", () => {
    clearTimeout(resizeTimer);
    resizeTimer = setTimeout(() => log("resize", { width: innerWidth, height: innerHeight }), 400);
  });
}

/** Where a suggestion goes: its face on the clicked point, turned as the engine placed it. */
function fromSuggestion(s, model, hit) {
  const q = G.rotationOf(G.fromColumnMajor(s.placement));
  return { modelId: model.id, category: s.category, size: model.size, parent: hit.objectId, point: hit.point,
    normal: hit.normal, face: s.attachment_face, q };
}

/** Canonical pose on a surface: the face geometry suggests, not turned (the list and search). */
function canonical(model, hit) {
  const face = G.geometricFace(model.size, hit.normal);
  return { modelId: model.id, category: model.category, size: model.size, parent: hit.objectId, point: hit.point,
    normal: hit.normal, face, q: G.attachRotation(face, hit.normal) };
}

/** One editing page at a time: a newer tab or window of the same session takes over and this one steps aside
 * (flushing what it logged), so two pages never number events or edit the scene side by side. */
function handOver() {
  if (!("BroadcastChannel" in window)) return;
  const channel = new BroadcastChannel(`scenesuggest-${boot.study}-${boot.token.slice(-12)}`);
  channel.onmessage = async (e) => {
    if (e.data?.type !== "hello" || e.data.page === boot.page_id) return;
    channel.close();
    document.body.classList.add("inactive");
    await outbox.flush();
    outbox.stop();
    say(strings.otherTab);
  };
  channel.postMessage({ type: "hello", page: boot.page_id });
}

async function main() {
  handOver();
  if (!boot.preview) {
    const state = await json("/session");
    outbox.resumeFrom(state.acked_seq);
  }
  const [models, target, start] = await Promise.all([json("/models"), json(`/scenes/${trial.scene}?which=target`),
    json(`/scenes/${trial.scene}?which=${boot.author ? "target" : "start"}`)]);  // authoring edits the target
  say("");
  const saved = localStorage.getItem(sceneKey);
  const scene = new SceneModel(saved ? JSON.parse(saved) : start);
  const library = new ModelLibrary(models.models, { onError: () => {
    banner.dataset.kind = "model";
    say(strings.modelFailed, { action: strings.retry, onAction: () => { banner.dataset.kind = ""; say(""); library.retry();
      for (const o of scene.objects.values()) if (o.parent !== null) editor.showObject(o); } });
  } });
  const viewer = new Viewer($("editor"));
  const editor = new Editor({ viewer, models: library, scene, condition: trial.condition, trial: trial.index, log, strings,
    onChange: () => {
      try { localStorage.setItem(sceneKey, JSON.stringify(scene.toJSON())); } catch (e) { /* storage full */ }
      $("delete-button").disabled = !editor.selected;
    } });
  viewer.startControls();
  viewer.setRoom(scene);
  viewer.setTarget(new SceneModel(target), (o) => library.instance(o.modelId, o.size), $("target"));
  logInputs(viewer);

  const fresh = !sessionStorage.getItem(sceneKey) && !saved;
  sessionStorage.setItem(sceneKey, "1");
  if (fresh) log("trial_start", { scene: trial.scene, condition: trial.condition });
  else log("resume", { reason: performance.getEntriesByType("navigation")[0]?.type || "reload" });
  outbox.flush();

  const hint = $("hint");
  let choice = null;  // none: the model chosen from the list, waiting for a click
  let current = null;  // basic/full: the object placed from the open suggestion list, and where
  let suggestMode = false;
  let panel = null;

  if (trial.condition === "none") {
    panel = new ModelListPanel($("model-panel"), { models: models.models, api, log, strings,
      onChoose: (model, how) => { choice = { model, how }; hint.textContent = strings.placing; } });
  } else {
    hint.textContent = strings.suggestHint;
    panel = new SuggestionPanel($("editor"), { api, log, strings, onPick: (s, model, how) => {
      if (!current) return;
      const spec = s ? fromSuggestion(s, model, current.hit) : canonical(model, current.hit);
      current.objectId = editor.replace(current.objectId, spec, how);
    } });
    $("suggest-mode").addEventListener("click", (e) => {
      suggestMode = !suggestMode;
      e.currentTarget.setAttribute("aria-pressed", String(suggestMode));
    });
  }

  async function suggestAt(hit, e) {
    let r;
    try {
      r = await api("/suggest", { method: "POST", body: JSON.stringify({ trial: trial.index, parent: hit.objectId,
        point: hit.point.toArray(), normal: hit.normal.toArray(), scene: scene.objectsJSON() }) });
    } catch (err) { say(strings.suggestOffline); return; }
    if (r.status === 410) { say(strings.ended, { action: strings.continue, onAction: () => location.assign(boot.next) }); return; }
    if (!r.ok) { say(strings.suggestOffline); return; }
    const data = await r.json();
    window.sceneSuggestTest.lastSuggest = { ...data, hit: { parent: hit.objectId, point: hit.point.toArray(), normal: hit.normal.toArray() } };
    log("context_query", { parent: hit.objectId, point: hit.point.toArray(), normal: hit.normal.toArray(), list_id: data.list_id });
    log("list_shown", { source: "context", items: data.suggestions.map((s) => s.category), list_id: data.list_id });
    if (!data.suggestions.length) return;
    const top = data.suggestions[0];
    current = { hit, objectId: editor.insert(fromSuggestion(top, top.models[0], hit), { source: "context", rank: 1, listId: data.list_id }) };
    panel.show(data, e.clientX, e.clientY);
  }

  editor.onClick = (e, hit, shift) => {
    if (trial.condition === "none") {
      if (choice && hit) {
        editor.insert(canonical(choice.model, hit), choice.how);
        choice = null;
        panel.clearChoice();
        hint.textContent = "";
        return;
      }
    } else if ((shift || suggestMode) && hit) {
      suggestAt(hit, e);
      return;
    } else if (panel.open) {
      panel.close();
      current = null;
    }
    editor.select(hit && !hit.room ? hit.objectId : null);
  };

  $("reset-view").addEventListener("click", () => { viewer.resetView(); log("camera", { action: "reset",
    distance: viewer.camera.position.distanceTo(viewer.controls.target) }); });
  $("undo-button").addEventListener("click", () => editor.undo());
  $("redo-button").addEventListener("click", () => editor.redo());
  $("delete-button").addEventListener("click", () => editor.deleteSelected());
  $("target").addEventListener("mouseenter", () => $("target").classList.add("large"));
  $("target").addEventListener("mouseleave", () => $("target").classList.remove("large"));

  if (boot.author) {
    authoring(scene, library, viewer);
  } else {
    const dialog = $("confirm-done");
    $("done-button").addEventListener("click", () => dialog.showModal());
    $("confirm-no").addEventListener("click", () => dialog.close());
    $("confirm-yes").addEventListener("click", () => { dialog.close(); finish(scene); });
  }

  window.sceneSuggestTest = {
    ready: false, condition: trial.condition, trial: trial.index, lastSuggest: null, events: testLog,
    worldToPixel: (x, y, z) => viewer.worldToPixel(x, y, z),
    objects: () => [...scene.objects.values()].map(SceneModel.toJSON),
    /** Pixel of the top centre of an object's box, to grab or select it. */
    topPixel: (id) => { const b = scene.worldBox(scene.objects.get(id)); const c = b.getCenter(new THREE.Vector3());
      return viewer.worldToPixel(c.x, b.max.y - 0.01, c.z); },
    centrePixel: (id) => { const c = scene.worldBox(scene.objects.get(id)).getCenter(new THREE.Vector3());
      return viewer.worldToPixel(c.x, c.y, c.z); },
    /** A pixel where the object itself is under the pointer (tables are mostly air in the middle). */
    grabPixel: (id) => {
      const b = scene.worldBox(scene.objects.get(id));
      for (const fy of [0.98, 0.5, 0.25, 0.75, 0.1]) {
        for (const [fx, fz] of [[0.5, 0.5], [0.3, 0.5], [0.7, 0.5], [0.5, 0.3], [0.5, 0.7], [0.2, 0.2], [0.8, 0.8]]) {
          const p = new THREE.Vector3(b.min.x + fx * (b.max.x - b.min.x), b.min.y + fy * (b.max.y - b.min.y), b.min.z + fz * (b.max.z - b.min.z));
          const [x, y] = viewer.worldToPixel(p.x, p.y, p.z);
          if (viewer.pick(x, y)?.objectId === id && document.elementFromPoint(x, y) === viewer.renderer.domElement) return [x, y];
        }
      }
      return null;
    },
    /** Pixel of the rotation ring of the selected object at ``deg`` degrees about its support normal
     * (0° = the plane's zero direction: +Z on floors). */
    ringPixel: (deg) => {
      const ring = editor.ring;
      if (!ring.visible) return null;
      const n = new THREE.Vector3(0, 0, 1).applyQuaternion(ring.quaternion);
      const zero = G.isHorizontal(n) ? new THREE.Vector3(0, 0, 1) : new THREE.Vector3(0, 1, 0);
      zero.addScaledVector(n, -zero.dot(n)).normalize();
      const p = zero.applyAxisAngle(n, THREE.MathUtils.degToRad(deg)).multiplyScalar(ring.scale.x).add(ring.position)
        .addScaledVector(n, -0.01);  // on the support plane, where the turn is measured
      return viewer.worldToPixel(p.x, p.y, p.z);
    },
    /** Select an object as a click on it would (for objects the default view hides). */
    select: (id) => editor.select(id),
    pickAt: (x, y) => { const h = viewer.pick(x, y); return h && { objectId: h.objectId, point: h.point.toArray(), normal: h.normal.toArray(), room: h.room }; },
    lastSeq: () => outbox.lastSeq,
    pending: () => outbox.pendingCount,
    frames: () => viewer.frames,
    /** The canvas's drawing-buffer and CSS sizes, and the frame time above which a moving view is drawn at a
     * lower resolution (settable, to exercise the adaptation on a fast machine). */
    resolution: () => ({ buffer: [viewer.renderer.domElement.width, viewer.renderer.domElement.height],
      css: [viewer.renderer.domElement.clientWidth, viewer.renderer.domElement.clientHeight], scale: viewer.scale }),
    setSlowFrameMs: (ms) => { viewer.slowFrameMs = ms; },
    /** What the last frame drew: draw calls and triangles (for the client benchmark). */
    renderInfo: () => ({ calls: viewer.renderer.info.render.calls, triangles: viewer.renderer.info.render.triangles }),
    /** Orbit the camera round its target for ``ms`` milliseconds, one step per animation frame; resolves the
     * frame rate the view kept up and the lowest resolution scale it used (``adaptive: false`` keeps it sharp). */
    orbit: (ms, { adaptive = true } = {}) => new Promise((resolve) => {
      const c = viewer.controls;
      viewer.adaptive = adaptive;
      viewer.lowestScale = 1;
      const offset = viewer.camera.position.clone().sub(c.target);
      const start = performance.now();
      const f0 = viewer.frames;
      const step = () => {
        const t = performance.now() - start;
        const turned = offset.clone().applyAxisAngle(new THREE.Vector3(0, 1, 0), t / 1000);
        viewer.camera.position.copy(c.target).add(turned);
        c.update();
        if (t < ms) requestAnimationFrame(step);
        else { viewer.adaptive = true; resolve({ fps: (viewer.frames - f0) / (t / 1000), scale: viewer.lowestScale }); }
      };
      requestAnimationFrame(step);
    }),
    firstFrameAt: () => viewer.firstFrameAt ?? null,
    targetObjects: () => viewer.target.objects,
    loaded: () => Promise.all([...viewer.meshes.values()].map((m) => m.userData.ready).concat([viewer.target.ready])),
  };
  viewer.loop();
  setInterval(() => { if (!boot.preview) api("/heartbeat", { method: "POST" }).catch(() => {}); }, 30000);
  window.sceneSuggestTest.ready = true;
}

/** The admin's authoring mode: save the scene as the study's target, render its target image. */
function authoring(scene, library, viewer) {
  const post = async (url, body) => {
    const r = await fetch(url, { method: "POST", credentials: "same-origin", body: JSON.stringify(body),
      headers: { "Content-Type": "application/json", "X-CSRF-Token": boot.author.csrf } });
    const data = await r.json().catch(() => ({ error: `HTTP ${r.status}` }));
    if (!r.ok) throw new Error(data.field ? `${data.error} (${data.field})` : data.error);
    return data;
  };
  const busy = async (button, work) => {
    button.disabled = true;
    try { say(await work()); } catch (e) { say(strings.saveFailed.replace("{error}", e.message)); }
    finally { button.disabled = false; }
  };
  if (boot.author.frozen) say(strings.frozen);
  $("save-button").addEventListener("click", (e) => busy(e.currentTarget, async () => {
    const saved = await post(boot.author.save, { scene: scene.toJSON() });
    viewer.setTarget(new SceneModel(scene.toJSON()), (o) => library.instance(o.modelId, o.size), $("target"));
    window.sceneSuggestTest.saved = saved;
    return strings.saved.replace("{file}", boot.author.file).replace("{n}", saved.objects);
  }));
  $("image-button").addEventListener("click", (e) => busy(e.currentTarget, async () => {
    const png = await renderImage(scene, (o) => library.instance(o.modelId, o.size));
    const saved = await post(boot.author.image, { png });
    window.sceneSuggestTest.imageSaved = saved;
    return strings.imageSaved.replace("{w}", saved.width).replace("{h}", saved.height);
  }));
}

async function finish(scene) {
  log("trial_done", { objects: scene.objects.size - 1 });
  await outbox.flush();
  for (let attempt = 0; ; attempt += 1) {
    try {
      const r = await api("/trial/done", { method: "POST", body: JSON.stringify({ trial: trial.index, scene: scene.objectsJSON() }) });
      if (r.ok || r.status === 409 || r.status === 410) {  // done, done before, or the session has ended
        localStorage.removeItem(sceneKey);
        location.assign(boot.next);
        return;
      }
    } catch (e) { /* offline: keep trying */ }
    say(strings.offline);
    await new Promise((res) => setTimeout(res, Math.min(30000, 1000 * 2 ** attempt)));
  }
}

$("trial-count").textContent = boot.preview ? "" : trial.kind === "practice" ? strings.practice
  : strings.sceneOf.replace("{n}", trial.number).replace("{of}", trial.of);
main();
