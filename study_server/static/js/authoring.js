// The experimenter's target editor: the same editor as a trial, opened on a scene's target, with "Save target"
// (the scene becomes the study's target file) and "Save image" (the target image rendered beside it) instead of
// "Done". Both go to the admin routes with the admin's session cookie and CSRF token.
import { SceneModel } from "./scene-model.js";
import { renderImage } from "./viewer.js";

const $ = (id) => document.getElementById(id);

/** POST JSON to an admin route; resolves its JSON answer or throws an Error with the server's message. */
async function post(author, url, body) {
  const r = await fetch(url, { method: "POST", credentials: "same-origin", body: JSON.stringify(body),
    headers: { "Content-Type": "application/json", "X-CSRF-Token": author.csrf } });
  const data = await r.json().catch(() => ({ error: `HTTP ${r.status}` }));
  if (!r.ok) throw new Error(data.field ? `${data.error} (${data.field})` : data.error);
  return data;
}

/**
 * Wire the save buttons. ``author``: the boot data's ``author`` (``csrf``, ``save`` and ``image`` URLs, ``file``,
 * ``frozen``); ``say`` shows a line in the banner; ``onSaved(result)`` and ``onImageSaved(result)`` hear each save.
 */
export function authoring({ author, scene, library, viewer, strings, say, onSaved = () => {}, onImageSaved = () => {} }) {
  const instance = (o) => library.instance(o.modelId, o.size);
  const busy = async (button, work) => {
    button.disabled = true;
    try { say(await work()); } catch (e) { say(strings.saveFailed.replace("{error}", e.message)); }
    finally { button.disabled = false; }
  };
  if (author.frozen) say(strings.frozen);
  $("save-button").addEventListener("click", (e) => busy(e.currentTarget, async () => {
    const saved = await post(author, author.save, { scene: scene.toJSON() });
    viewer.setTarget(new SceneModel(scene.toJSON()), instance, $("target"));
    onSaved(saved);
    return strings.saved.replace("{file}", author.file).replace("{n}", saved.objects);
  }));
  $("image-button").addEventListener("click", (e) => busy(e.currentTarget, async () => {
    const saved = await post(author, author.image, { png: await renderImage(scene, instance) });
    onImageSaved(saved);
    return strings.imageSaved.replace("{w}", saved.width).replace("{h}", saved.height);
  }));
}
