// The device check (study_server/participants/device.py): tests for real what the trial page needs — the import map, storage,
// pointer events, ResizeObserver, dialogs, a WebGL 2 context like the editor's, its shaders compiling — then draws a
// small scene with the editor's renderer and materials and measures the frame rate; reports it all, and continues.
// This module imports nothing statically, so it runs even where the import map does not (that is then reported).
const form = document.getElementById("device-form");
const PROBE_MS = 2000;  // the longest the frame-rate probe draws (study_server.participants.device.PROBE_SECONDS)
const PROBE_FRAMES = 30;  // … or until it has timed this many frames, after a few to warm up
const WARM_UP = 3;

/** Whether a check passes; a check that throws fails. */
function passes(check) {
  try { return !!check(); } catch (e) { return false; }
}

const FEATURES = {
  storage: () => {  // the outbox and the scene kept across reloads (blocked in some private windows)
    const key = "scenesuggest-device-check";
    localStorage.setItem(key, "1");
    const kept = localStorage.getItem(key) === "1";
    localStorage.removeItem(key);
    return kept;
  },
  pointer_events: () => "PointerEvent" in window && "setPointerCapture" in Element.prototype,
  resize_observer: () => "ResizeObserver" in window,
  dialog: () => typeof HTMLDialogElement === "function" && "showModal" in HTMLDialogElement.prototype,
};

const nextFrame = () => new Promise((resolve) => requestAnimationFrame(resolve));
/** Resolves once the page shows (a link opened in a background tab is checked when the participant looks). */
const visible = () => new Promise((resolve) => {
  if (!document.hidden) { resolve(); return; }
  const shown = () => { if (!document.hidden) { document.removeEventListener("visibilitychange", shown); resolve(); } };
  document.addEventListener("visibilitychange", shown);
});
const RETRIES_KEY = "scenesuggest-device-retries";
const MAX_FPS = 1000;  // study_server.participants.device.MAX_FPS

/** A small room with the editor's materials, drawn by a renderer made as the editor makes it: what is missing
 * ("webgl2", "shaders") and the frames per second it drew, with the GPU's name where the browser gives it. */
async function probe(THREE, shading) {
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: false });
  } catch (e) {
    return { missing: ["webgl2"] };
  }
  let shaderFailed = false;
  renderer.debug.onShaderError = () => { shaderFailed = true; };
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  renderer.setSize(320, 200);
  document.getElementById("device-probe").append(renderer.domElement);
  const scene = new THREE.Scene();
  shading.addLights(scene);
  const floor = new THREE.Mesh(new THREE.PlaneGeometry(4, 4), shading.matteMaterial({ colour: 0xc9a77c }));
  floor.rotation.x = -Math.PI / 2;
  scene.add(floor);
  const group = new THREE.Group();
  for (let i = 0; i < 24; i += 1) {
    const material = i % 2 ? shading.matteMaterial({ colour: 0x4477aa + i * 0x0a0a0a })
      : new THREE.MeshLambertMaterial({ color: 0xaa7744 });  // three.js's own lighting, as textured models use
    const box = new THREE.Mesh(new THREE.BoxGeometry(0.3, 0.3 + (i % 4) * 0.1, 0.3), material);
    box.position.set((i % 6) * 0.5 - 1.25, 0.25, Math.floor(i / 6) * 0.5 - 0.75);
    group.add(box);
  }
  scene.add(group);
  const camera = new THREE.PerspectiveCamera(50, 320 / 200, 0.05, 100);
  camera.position.set(2.5, 2.2, 3);
  camera.lookAt(0, 0, 0);
  const gl = renderer.getContext();
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER) || "").slice(0, 200);
  renderer.compile(scene, camera);
  renderer.render(scene, camera);
  if (shaderFailed || gl.isContextLost()) return { missing: ["shaders"], renderer: name };
  let frames = -WARM_UP;
  let from = 0;
  let began = performance.now();
  for (;;) {
    await visible();
    await nextFrame();
    if (document.hidden) {  // a tab in the background draws no frames: time only while it shows
      frames = -WARM_UP;
      began = performance.now();
      continue;
    }
    group.rotation.y += 0.02;
    renderer.render(scene, camera);
    gl.finish?.();
    frames += 1;
    const now = performance.now();
    if (frames === 0) from = now;
    if (frames >= PROBE_FRAMES || now - began >= PROBE_MS) {
      const fps = frames > 0 && now > from ? (frames * 1000) / (now - from) : 0;
      renderer.dispose();
      return { missing: shaderFailed ? ["shaders"] : [], fps, renderer: name };
    }
  }
}

async function check() {
  const missing = Object.entries(FEATURES).filter(([, test]) => !passes(test)).map(([name]) => name);
  let result = { missing: ["importmap"] };
  const mapped = !HTMLScriptElement.supports || HTMLScriptElement.supports("importmap");
  const loaded = mapped && await Promise.all([import("three"), import("./shading.js")]).catch(() => null);
  if (mapped && !loaded) {  // import maps work here: the download failed (a flaky network); load the page again
    let retries = 2;
    try {
      retries = Number(sessionStorage.getItem(RETRIES_KEY) || 0);
      sessionStorage.setItem(RETRIES_KEY, String(retries + 1));
    } catch (e) { /* storage blocked: no retry (it is reported as missing anyway) */ }
    if (retries < 2) {
      setTimeout(() => location.reload(), 1000 * (retries + 1));
      return;
    }
  }
  if (loaded) result = await probe(...loaded).catch(() => ({ missing: ["webgl2"] }));
  missing.push(...result.missing);
  form.missing.value = missing.join(",");
  form.width.value = String(window.innerWidth);
  form.height.value = String(window.innerHeight);
  form.pixel_ratio.value = String(window.devicePixelRatio || 1);
  const coarse = window.matchMedia && window.matchMedia("(pointer: coarse)").matches;
  const fine = window.matchMedia && window.matchMedia("(any-pointer: fine)").matches;
  form.touch_only.value = coarse && !fine ? "true" : "false";
  form.fps.value = result.fps === undefined ? "" : Math.min(result.fps, MAX_FPS).toFixed(2);
  // the GPU's name as the server takes it: printable, within the Basic Multilingual Plane, 200 characters
  form.renderer.value = (result.renderer || "").replace(/[^\x20-\x7e\u00a0-\uffff]/gu, "").slice(0, 200);
  form.submit();
}

if (form) check();
