// The trial page's shell: boot data, outbox, heartbeat and the "done" flow. The 3D editor mounts into
// #editor (editor modules build on this shell).
import { Outbox } from "./outbox.js";

const boot = JSON.parse(document.getElementById("boot").textContent);
const status = document.getElementById("status");
const messages = { saving: "Saving…", saved: "", offline: "Connection lost — your work is kept and will be sent when it is back." };
const outbox = new Outbox({ api: boot.api, token: boot.token, pageId: boot.page_id, study: boot.study,
  onStatus: (s) => { status.textContent = messages[s] ?? ""; status.dataset.state = s; } });
const api = (path, options = {}) => fetch(`${boot.api}${path}`, { ...options,
  headers: { "Content-Type": "application/json", Authorization: `Bearer ${boot.token}`, ...(options.headers || {}) } });

const trial = boot.trial;
document.getElementById("trial-count").textContent = boot.preview ? ""
  : trial.kind === "practice" ? "Practice" : `Scene ${trial.number} of ${trial.of}`;

async function start() {
  if (!boot.preview) {
    const state = await api("/session").then((r) => r.json()).catch(() => null);
    if (state) outbox.resumeFrom(state.acked_seq);
  }
  const fresh = !sessionStorage.getItem(`trial-${boot.token.slice(-8)}-${trial.index}`);
  sessionStorage.setItem(`trial-${boot.token.slice(-8)}-${trial.index}`, "1");
  outbox.log(fresh ? "trial_start" : "resume", fresh ? { scene: trial.scene, condition: trial.condition }
    : { reason: performance.getEntriesByType("navigation")[0]?.type || "reload" }, trial.index);
  outbox.flush();
  setInterval(() => { if (!boot.preview) api("/heartbeat", { method: "POST" }).catch(() => {}); }, 30000);
}

export async function finishTrial(scene) {
  outbox.log("trial_done", { objects: scene ? scene.objects.length : 0 }, trial.index);
  await outbox.flush();
  for (let attempt = 0; ; attempt += 1) {
    try {
      const r = await api("/trial/done", { method: "POST", body: JSON.stringify({ trial: trial.index, scene }) });
      if (r.ok || r.status === 409) { location.assign(boot.next); return; }
    } catch (e) { /* offline: keep trying */ }
    status.textContent = messages.offline;
    await new Promise((r) => setTimeout(r, Math.min(30000, 1000 * 2 ** attempt)));
  }
}

const dialog = document.getElementById("confirm-done");
document.getElementById("done-button").addEventListener("click", () => dialog.showModal());
document.getElementById("confirm-no").addEventListener("click", () => dialog.close());
document.getElementById("confirm-yes").addEventListener("click", () => {
  dialog.close();
  finishTrial(window.sceneSuggestEditor?.sceneJSON() ?? null);
});

window.sceneSuggest = { boot, outbox, api, finishTrial };
start();
