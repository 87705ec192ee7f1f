// The page's hook for the browser tests and the client benchmark, as `window.sceneSuggestTest`. trial.js imports
// this module only when `window.sceneSuggestTestHook` is set before the page's scripts run, or `sceneSuggestTestHook`
// is in the tab's sessionStorage (tests/browser/engines.py): a participant's page does not load it. It only reads
// the page (and can take the WebGL context away, as a GPU reset would), so a participant who switches it on in their
// own tab gains nothing their browser's developer tools do not give. It records what the page logs and reports, and
// converts world points to pixels so that tests click real pixels on real objects instead of guessing coordinates.
import * as THREE from "three";
import * as G from "./geometry.js";
import { SceneModel } from "./scene-model.js";

/**
 * Install `window.sceneSuggestTest` (``ready`` false until ``attach``) and return what the page reports to:
 * ``logged`` each event, ``suggested`` each context list, ``saved`` / ``imageSaved`` each authoring save, and
 * ``attach`` the editor once it runs.
 */
export function installTestHook(trial) {
  const hook = { ready: false, condition: trial.condition, trial: trial.index, events: [], lastSuggest: null,
    saved: null, imageSaved: null };
  window.sceneSuggestTest = hook;
  return {
    logged: (seq, type, payload) => { hook.events.push({ seq, type, payload }); },
    suggested: (response, hit) => {
      hook.lastSuggest = { ...response, hit: { parent: hit.objectId, point: hit.point.toArray(), normal: hit.normal.toArray() } };
    },
    saved: (result) => { hook.saved = result; },
    imageSaved: (result) => { hook.imageSaved = result; },
    /** Add the helpers that read the page's viewer, scene, editor and outbox, and mark the page ready. */
    attach: (page) => { Object.assign(hook, pixelHelpers(page), stateHelpers(page)); hook.ready = true; },
  };
}

/** Pixels of things on screen (CSS pixels of the viewport), and the editor's reaction to them. */
function pixelHelpers({ viewer, scene, editor }) {
  const box = (id) => scene.worldBox(scene.objects.get(id));
  return {
    worldToPixel: (x, y, z) => viewer.worldToPixel(x, y, z),
    /** Pixel of the top centre of an object's box, to grab or select it. */
    topPixel: (id) => { const b = box(id); const c = b.getCenter(new THREE.Vector3());
      return viewer.worldToPixel(c.x, b.max.y - 0.01, c.z); },
    centrePixel: (id) => { const c = box(id).getCenter(new THREE.Vector3()); return viewer.worldToPixel(c.x, c.y, c.z); },
    grabPixel: (id) => grabPixel(viewer, box(id), id),
    ringPixel: (deg) => ringPixel(viewer, editor.ring, deg),
    /** Select an object as a click on it would (for objects the default view hides). */
    select: (id) => editor.select(id),
    pickAt: (x, y) => { const h = viewer.pick(x, y);
      return h && { objectId: h.objectId, point: h.point.toArray(), normal: h.normal.toArray(), room: h.room }; },
  };
}

/** A pixel where the object itself is under the pointer (tables are mostly air in the middle), or null. */
function grabPixel(viewer, b, id) {
  for (const fy of [0.98, 0.5, 0.25, 0.75, 0.1]) {
    for (const [fx, fz] of [[0.5, 0.5], [0.3, 0.5], [0.7, 0.5], [0.5, 0.3], [0.5, 0.7], [0.2, 0.2], [0.8, 0.8]]) {
      const p = new THREE.Vector3(b.min.x + fx * (b.max.x - b.min.x), b.min.y + fy * (b.max.y - b.min.y), b.min.z + fz * (b.max.z - b.min.z));
      const [x, y] = viewer.worldToPixel(p.x, p.y, p.z);
      if (viewer.pick(x, y)?.objectId === id && document.elementFromPoint(x, y) === viewer.renderer.domElement) return [x, y];
    }
  }
  return null;
}

/** Pixel of the selected object's rotation ring at ``deg`` degrees about its support normal (0° = the plane's
 * zero direction: +Z on floors), on the support plane under the ring (a whole pixel there is within the ring's hit
 * area), or null when no ring shows. */
function ringPixel(viewer, ring, deg) {
  if (!ring.visible) return null;
  const n = new THREE.Vector3(0, 0, 1).applyQuaternion(ring.quaternion);
  const zero = G.isHorizontal(n) ? new THREE.Vector3(0, 0, 1) : new THREE.Vector3(0, 1, 0);
  zero.addScaledVector(n, -zero.dot(n)).normalize();
  const p = zero.applyAxisAngle(n, THREE.MathUtils.degToRad(deg)).multiplyScalar(ring.scale.x).add(ring.position)
    .addScaledVector(n, -0.01);  // on the support plane, where the turn is measured (within the ring's hit area)
  return viewer.worldToPixel(p.x, p.y, p.z);
}

/** The scene, the outbox and the renderer as the page holds them. */
function stateHelpers({ viewer, scene, outbox }) {
  const canvas = viewer.renderer.domElement;
  let lose = null;
  return {
    objects: () => [...scene.objects.values()].map(SceneModel.toJSON),
    lastSeq: () => outbox.lastSeq,
    pending: () => outbox.pendingCount,
    frames: () => viewer.frames,
    /** The canvas's drawing-buffer and CSS sizes, and the frame time above which a moving view is drawn at a
     * lower resolution (settable, to exercise the adaptation on a fast machine). */
    resolution: () => ({ buffer: [canvas.width, canvas.height], css: [canvas.clientWidth, canvas.clientHeight],
      scale: viewer.scale }),
    setSlowFrameMs: (ms) => { viewer.slowFrameMs = ms; },
    /** What the last frame drew: draw calls and triangles (for the client benchmark). */
    renderInfo: () => ({ calls: viewer.renderer.info.render.calls, triangles: viewer.renderer.info.render.triangles }),
    orbit: (ms, options) => orbit(viewer, ms, options),
    firstFrameAt: () => viewer.firstFrameAt ?? null,
    /** Take the editor's WebGL context away, or give it back, as a GPU reset would (WEBGL_lose_context; the
     * extension is asked for while the context lives: a lost context gives none). */
    loseContext: () => { lose = viewer.renderer.getContext().getExtension("WEBGL_lose_context"); lose.loseContext();
      return true; },
    restoreContext: () => { lose.restoreContext(); return true; },
    targetObjects: () => viewer.target.objects,
    loaded: () => Promise.all([...viewer.meshes.values()].map((m) => m.userData.ready).concat([viewer.target.ready])),
  };
}

/** Orbit the camera round its target for ``ms`` milliseconds, one step per animation frame; resolves the frame
 * rate the view kept up and the lowest resolution scale it used (``adaptive: false`` keeps it sharp). */
function orbit(viewer, ms, { adaptive = true } = {}) {
  return new Promise((resolve) => {
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
  });
}
