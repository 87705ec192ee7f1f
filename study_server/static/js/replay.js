// The admin's replay of a trial: the participants' editor, read-only, showing the scene after each event as the
// server's replay (scenesuggest/contract/replay.py) rebuilt it. A scrubber and the event list move through the events,
// play runs them at 1×, 4× or 16× the participant's own pace, the camera is free and the target is inset.
import { ModelLibrary } from "./models.js";
import { SceneModel } from "./scene-model.js";
import { Viewer } from "./viewer.js";

const $ = (id) => document.getElementById(id);
const boot = JSON.parse($("boot").textContent);

/** "m:ss.s" of a duration in ms. */
function clock(ms) {
  const s = Math.max(0, ms) / 1000;
  return `${Math.floor(s / 60)}:${(s % 60).toFixed(1).padStart(4, "0")}`;
}

class Replay {
  constructor(data) {
    this.data = data;
    this.events = data.events;
    this.t0 = this.events.length ? this.events[0].t : 0;
    this.viewer = new Viewer($("editor"));
    this.viewer.startControls();
    this.library = new ModelLibrary(data.models);
    this.shown = new Map();  // object id → {modelId, key} of what is on screen
    this.position = 0;  // 0: the start scene; i: the scene after event i − 1
    this.speed = 1;
    this.playing = false;
    this.rebuilt = { index: 0, scene: new Map(data.start.map((o) => [o.id, o])) };
    const start = new SceneModel({ objects: data.start });
    this.viewer.setRoom(start);
    this.viewer.setTarget(new SceneModel({ objects: data.target }), (o) => this.library.instance(o.modelId, o.size),
      $("target"));
    this.list = this.makeList();
    const scrubber = $("scrubber");
    scrubber.max = String(this.events.length);
    scrubber.addEventListener("input", () => { this.pause(); this.go(Number(scrubber.value)); });
    $("play").addEventListener("click", () => (this.playing ? this.pause() : this.play()));
    $("speed").addEventListener("change", (e) => { this.speed = Number(e.target.value); });
    $("reset-view").addEventListener("click", () => this.viewer.resetView());
    this.go(0);
    this.viewer.loop();
  }

  makeList() {
    const list = $("events");
    let scene = 0;
    const items = this.events.map((e, i) => {
      const li = document.createElement("li");
      li.dataset.position = String(i + 1);
      if (e.scene !== scene) li.classList.add("changes");
      scene = e.scene;
      const at = document.createElement("span");
      at.className = "at";
      at.textContent = clock(e.t - this.t0);
      li.append(at, document.createTextNode(`${e.seq} · ${e.label}`));
      li.addEventListener("click", () => { this.pause(); this.go(i + 1); });
      return li;
    });
    list.replaceChildren(...items);
    return items;
  }

  /** Scene ``index``'s objects: the start with the document's first ``index`` steps applied (each step sets the
   * states an event changed and takes away what it removed), from the last scene rebuilt when going forward. */
  sceneObjects(index) {
    if (index < this.rebuilt.index) {
      this.rebuilt = { index: 0, scene: new Map(this.data.start.map((o) => [o.id, o])) };
    }
    const { scene } = this.rebuilt;
    for (let k = this.rebuilt.index; k < index; k += 1) {
      const change = this.data.steps[k];
      for (const id of change.removed) scene.delete(id);
      for (const o of change.set) scene.set(o.id, o);
    }
    this.rebuilt.index = index;
    return [...scene.values()];
  }

  /** The scene index and time of a position. */
  sceneAt(position) { return position === 0 ? 0 : this.events[position - 1].scene; }

  timeAt(position) { return position === 0 ? this.t0 : this.events[position - 1].t; }

  /** Show the scene at ``position``: objects added, moved or taken away to match it. */
  go(position) {
    this.position = Math.max(0, Math.min(this.events.length, position));
    const objects = this.sceneObjects(this.sceneAt(this.position)).filter((o) => o.parent !== null);
    const wanted = new Map(objects.map((o) => [o.id, SceneModel.fromJSON(o)]));
    for (const id of [...this.shown.keys()]) {
      if (!wanted.has(id)) { this.viewer.removeObject(id); this.shown.delete(id); }
    }
    for (const [id, o] of wanted) {
      const key = o.matrix.elements.join(",");
      const was = this.shown.get(id);
      if (was && was.modelId === o.modelId) {
        if (was.key !== key) this.viewer.moveObject(id, o.matrix);
      } else {
        this.viewer.setObject(id, this.library.instance(o.modelId, o.size), o.matrix);
      }
      this.shown.set(id, { modelId: o.modelId, key, matrix: o.matrix.elements.slice() });
    }
    $("scrubber").value = String(this.position);
    $("clock").textContent = clock(this.timeAt(this.position) - this.t0);
    $("position").textContent = `event ${this.position} of ${this.events.length} · ${wanted.size} object(s)`;
    for (const li of this.list) li.removeAttribute("aria-current");
    const current = this.list[this.position - 1];
    if (current) { current.setAttribute("aria-current", "true"); current.scrollIntoView({ block: "nearest" }); }
  }

  play() {
    if (this.position >= this.events.length) this.go(0);
    this.playing = true;
    $("play").setAttribute("aria-pressed", "true");
    $("play").textContent = "Pause";
    let head = this.timeAt(this.position);
    let last = performance.now();
    const step = (now) => {
      if (!this.playing) return;
      head += (now - last) * this.speed;
      last = now;
      let next = this.position;
      while (next < this.events.length && this.events[next].t <= head) next += 1;
      if (next !== this.position) this.go(next);
      if (this.position >= this.events.length) { this.pause(); return; }
      requestAnimationFrame(step);
    };
    requestAnimationFrame(step);
  }

  pause() {
    this.playing = false;
    $("play").setAttribute("aria-pressed", "false");
    $("play").textContent = "Play";
  }

  /** What is on screen (object id → column-major matrix), for scripts and the browser test. */
  onScreen() {
    return Object.fromEntries([...this.shown].map(([id, s]) => [id, s.matrix]));
  }
}

async function main() {
  const response = await fetch(boot.data);
  if (!response.ok) {
    $("banner").textContent = `The trial could not be loaded (${response.status}).`;
    $("banner").hidden = false;
    return;
  }
  const data = await response.json();
  if (data.problem) {
    $("banner").textContent = data.problem;
    $("banner").hidden = false;
  }
  window.sceneSuggestReplay = new Replay(data);
}

main();
