// The trial page: loads the scenes and models, wires the editor to the study's condition, logs every
// interaction through the outbox, keeps the scene across reloads, and finishes the trial.
import { setUpCondition } from "./conditions.js";
import { Editor } from "./editor.js";
import { ModelLibrary } from "./models.js";
import { Outbox } from "./outbox.js";
import { SceneModel } from "./scene-model.js";
import { Viewer } from "./viewer.js";

const boot = JSON.parse(document.getElementById("boot").textContent);
const strings = JSON.parse(document.getElementById("strings").textContent);
const trial = boot.trial;
const $ = (id) => document.getElementById(id);
const banner = $("banner");
let testHook = null;  // only on a page a test opened with `window.sceneSuggestTestHook` set

let lasting = { text: "" };  // what the banner says once a transient line goes

/** Show ``text`` in the banner (or hide it when empty), with an ``action`` button if given. A ``transient`` line
 * (about the connection) shows over the lasting one and goes when the outbox next reaches the server; a lasting
 * line stays until the page says something else. */
function say(text, { action = null, onAction = null, transient = false } = {}) {
  if (!transient) lasting = { text, action, onAction };
  show(text, action, onAction);
  banner.dataset.kind = !text ? "" : transient ? "transient" : "lasting";
}

function show(text, action, onAction) {
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

const sayEnded = () => say(strings.ended, { action: strings.continue, onAction: () => location.assign(boot.next) });
const outbox = new Outbox({ api: boot.api, token: boot.token, pageId: boot.page_id, study: boot.study,
  batch: boot.batch, vocabulary: boot.vocabulary,
  onStatus: (s) => {
    if (s === "offline") say(strings.offline, { transient: true });
    else if (s === "ended") sayEnded();
    else if (banner.dataset.kind === "transient") say(lasting.text, lasting);
    banner.dataset.state = s;
  } });
/** The JSON API. A 429 (this session asked for more lists than a person does) is waited out as the server says
 * (Retry-After, up to a minute) and asked again, twice at most; the answer after that is the caller's. */
const api = async (path, options = {}) => {
  for (let tries = 0; ; tries += 1) {
    const r = await fetch(`${boot.api}${path}`, { ...options,
      headers: { "Content-Type": "application/json", Authorization: `Bearer ${boot.token}`, ...(options.headers || {}) } });
    const wait = Number(r.headers.get("Retry-After"));
    if (r.status !== 429 || tries >= 2 || !(wait > 0 && wait <= 60)) return r;
    say(strings.wait, { transient: true });
    await new Promise((res) => setTimeout(res, wait * 1000));
  }
};
const log = (type, payload = {}) => {
  const seq = outbox.log(type, payload, trial.index);
  testHook?.logged(seq, type, payload);
  return seq;
};
const sceneKey = `scenesuggest-scene-${boot.study}-${boot.token.slice(-12)}-${trial.index}`;

async function json(path) {
  for (let attempt = 0; ; attempt += 1) {
    try {
      const r = await api(path);
      if (r.ok) return await r.json();
    } catch (e) { /* offline: retry */ }
    say(strings.offline, { transient: true });
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

/** Whether another page of this session took over, and the editor to disable then. */
let steppedAside = false;
let activeEditor = null;

/** One editing page at a time: a newer tab or window of the same session takes over and this one steps aside
 * (flushing what it logged), so two pages never number events or edit the scene side by side. */
function handOver() {
  if (!("BroadcastChannel" in window)) return;
  const channel = new BroadcastChannel(`scenesuggest-${boot.study}-${boot.token.slice(-12)}`);
  channel.onmessage = async (e) => {
    if (e.data?.type !== "hello" || e.data.page === boot.page_id) return;
    channel.close();
    steppedAside = true;
    if (activeEditor) activeEditor.disabled = true;
    $("confirm-done")?.close();
    document.body.inert = true;  // no button, list or dialog of this page acts any more, by pointer or by key
    document.body.classList.add("inactive");
    await outbox.flush();
    outbox.stop();
    say(strings.otherTab);
  };
  channel.postMessage({ type: "hello", page: boot.page_id });
}

/** The test hook, imported only when a test set `window.sceneSuggestTestHook` before the page's scripts ran, or
 * `sceneSuggestTestHook` in this tab's sessionStorage (where a driver that cannot run a script before the page's
 * own puts it: tests/browser/engines.py). */
async function loadTestHook() {
  let asked = !!window.sceneSuggestTestHook;
  try { asked ||= sessionStorage.getItem("sceneSuggestTestHook") === "1"; } catch (e) { /* storage blocked */ }
  if (!asked) return null;
  const { installTestHook } = await import("./test-hook.js");
  return installTestHook(trial);
}

/** The models, the target, and the scene to edit: the one this browser kept (from before a reload), unless the
 * server holds a newer change of this trial (the participant went on in another browser, or this one lost its
 * storage): then the scene the server's events rebuild, and the participant is told. Else the trial's start
 * (authoring edits the target itself). */
async function load() {
  if (!boot.preview) outbox.resumeFrom((await json("/session")).acked_seq);
  const which = boot.author ? "target" : boot.preview ? "start" : "progress";
  const [models, target, start] = await Promise.all([json("/models"), json(`/scenes/${trial.scene}?which=target`),
    json(`/scenes/${trial.scene}?which=${which}`)]);
  say("");
  const saved = localStorage.getItem(sceneKey);
  const savedSeq = Number(localStorage.getItem(`${sceneKey}-seq`) ?? -1);
  if (start.changes > 0 && (!saved || start.last_change_seq > savedSeq)) {
    say(strings.restored, { action: strings.close, onAction: () => say("") });
    return { models: models.models, target, scene: new SceneModel(start), saved: true };
  }
  return { models: models.models, target, scene: new SceneModel(saved ? JSON.parse(saved) : start), saved: !!saved };
}

/** A model that failed to load: the banner offers a retry, which shows the scene's models again. */
function modelFailed(library, scene, editor) {
  say(strings.modelFailed, { action: strings.retry, onAction: () => {
    say("");
    library.retry();
    for (const o of scene.objects.values()) if (o.parent !== null) editor.showObject(o);
  } });
}

/** The model library and the editor on the viewer; each change is kept in localStorage (for reloads) and updates
 * the Delete button. */
function makeEditor(viewer, models, scene) {
  const library = new ModelLibrary(models, { onError: () => modelFailed(library, scene, editor) });
  const editor = new Editor({ viewer, models: library, scene, condition: trial.condition, trial: trial.index, log, strings,
    onChange: () => {
      if (steppedAside) return;  // the newer page keeps the scene now
      // kept once the change's event is logged (the editor logs it after this call), with its seq
      queueMicrotask(() => {
        try {
          localStorage.setItem(sceneKey, JSON.stringify(scene.toJSON()));
          localStorage.setItem(`${sceneKey}-seq`, String(outbox.lastSeq));
        } catch (e) { /* storage full */ }
      });
      $("delete-button").disabled = !editor.selected;
    } });
  editor.disabled = steppedAside;
  activeEditor = editor;
  return { library, editor };
}

/** The first visit to this trial logs its start (after the condition's instructions, when the page before it
 * showed them: how long they were open, on the server's clock); a reload or a return to it logs a resume. */
function logStart(saved) {
  const fresh = !sessionStorage.getItem(sceneKey) && !saved;
  sessionStorage.setItem(sceneKey, "1");
  if (fresh && trial.briefing !== null && trial.briefing !== undefined) {
    log("briefing", { condition: trial.condition, seconds: trial.briefing });
  }
  if (fresh) log("trial_start", { scene: trial.scene, condition: trial.condition });
  else log("resume", { reason: performance.getEntriesByType("navigation")[0]?.type || "reload" });
  outbox.flush();
}

/** A WebGL context the browser takes away mid-trial (a GPU reset, too many contexts): the participant is told and
 * may reload (the scene and the outbox are kept); when the browser gives it back, three.js rebuilds what it drew
 * and the view goes on. The server hears of both as client_error events. */
function watchContext(viewer) {
  const canvas = viewer.renderer.domElement;
  canvas.addEventListener("webglcontextlost", () => {
    log("client_error", { message: "WebGL context lost" });
    outbox.flush();
    say(strings.contextLost, { action: strings.reload, onAction: () => location.reload() });
  });
  canvas.addEventListener("webglcontextrestored", () => {
    log("client_error", { message: "WebGL context restored" });
    say("");
    viewer.invalidate();
  });
}

function wireToolbar(viewer, editor) {
  $("reset-view").addEventListener("click", () => { viewer.resetView(); log("camera", { action: "reset",
    distance: viewer.camera.position.distanceTo(viewer.controls.target) }); });
  $("undo-button").addEventListener("click", () => editor.undo());
  $("redo-button").addEventListener("click", () => editor.redo());
  $("delete-button").addEventListener("click", () => editor.deleteSelected());
  for (const [on, large] of [["mouseenter", true], ["mouseleave", false], ["focus", true], ["blur", false]]) {
    $("target").addEventListener(on, () => $("target").classList.toggle("large", large));  // the keyboard's too
  }
}

/** The target picture's text alternative: the objects the target scene holds, by category ("2 × chair"), named as
 * the model list names them in the participant's language (``label``). */
function describeTarget(target, models) {
  const labels = new Map(models.filter((m) => m.label).map((m) => [m.category, m.label]));
  const counts = new Map();
  for (const o of target.objects || []) {
    if (o.parent === null || o.parent === undefined) continue;  // the room
    const shown = labels.get(o.category) || o.category.replace(/([a-z0-9])([A-Z])/g, "$1 $2");
    const name = document.documentElement.lang === "en" ? shown.toLowerCase() : shown;  // (German nouns keep capitals)
    counts.set(name, (counts.get(name) || 0) + 1);
  }
  const listed = [...counts].map(([name, n]) => (n > 1 ? `${n} × ${name}` : name)).join(", ");
  return strings.targetAlt.replace("{objects}", () => listed || strings.targetEmpty);
}

/** Done asks for confirmation, then finishes the trial. */
function wireDone(scene) {
  const dialog = $("confirm-done");
  $("done-button").addEventListener("click", () => dialog.showModal());
  $("confirm-no").addEventListener("click", () => dialog.close());
  $("confirm-yes").addEventListener("click", () => { dialog.close(); finish(scene); });
}

async function main() {
  testHook = await loadTestHook();
  handOver();
  const { models, target, scene, saved } = await load();
  let viewer;
  try {
    viewer = new Viewer($("editor"));
  } catch (e) {  // no WebGL (switched off, blocklisted, no driver): say so, not a grey page; the server hears it
    log("client_error", { message: `no WebGL: ${String(e?.message ?? e).slice(0, 300)}` });
    outbox.flush();
    say(strings.noWebgl);
    return;
  }
  watchContext(viewer);
  const { library, editor } = makeEditor(viewer, models, scene);
  viewer.startControls();
  viewer.setRoom(scene);
  viewer.setTarget(new SceneModel(target), (o) => library.instance(o.modelId, o.size), $("target"));
  $("target").setAttribute("aria-label", describeTarget(target, models));
  logInputs(viewer);
  logStart(saved);
  setUpCondition(trial.condition, { editor, scene, models, trial: trial.index, api, log, strings, say,
    onEnded: sayEnded, onSuggestions: testHook?.suggested });
  wireToolbar(viewer, editor);
  if (boot.author) {  // the experimenter's target editor: a module participants' pages never load
    const { authoring } = await import("./authoring.js");
    authoring({ author: boot.author, scene, library, viewer, strings, say, onSaved: testHook?.saved,
      onImageSaved: testHook?.imageSaved });
  } else {
    wireDone(scene);
  }
  viewer.loop();
  setInterval(() => { if (!boot.preview) api("/heartbeat", { method: "POST" }).catch(() => {}); }, 30000);
  testHook?.attach({ viewer, scene, editor, outbox });
}

async function finish(scene) {
  if (steppedAside) return;  // the newer page finishes the trial
  log("trial_done", { objects: scene.objects.size - 1 });
  await outbox.flush();
  for (let attempt = 0; ; attempt += 1) {
    try {
      const r = await api("/trial/done", { method: "POST", body: JSON.stringify({ trial: trial.index, scene: scene.objectsJSON(), last_seq: outbox.lastSeq }) });
      if (r.ok || r.status === 409 || r.status === 410) {  // done, done before, or the session has ended
        localStorage.removeItem(sceneKey);
        localStorage.removeItem(`${sceneKey}-seq`);
        location.assign(boot.next);
        return;
      }
    } catch (e) { /* offline: keep trying */ }
    say(strings.offline, { transient: true });
    await new Promise((res) => setTimeout(res, Math.min(30000, 1000 * 2 ** attempt)));
  }
}

$("trial-count").textContent = boot.preview ? "" : trial.kind === "practice" ? strings.practice
  : strings.sceneOf.replace("{n}", trial.number).replace("{of}", trial.of);
main();
