// What differs between the study's conditions. In "none" the participant chooses a model from the fixed list
// (or a keyword search) and clicks where it goes; it stands there in its canonical pose. In "basic" and "full" a
// shift-click on a surface (or a click while "Suggest here" is on) asks for suggestions at that point (a context
// query): the top one is placed at once, and picking another in the panel replaces it in place. The server turns
// each suggestion's placement as the engine oriented it in "full" and leaves it canonical in "basic", so the page
// places both alike.
import * as G from "./geometry.js";
import { ModelListPanel, SuggestionPanel } from "./panels.js";

const $ = (id) => document.getElementById(id);

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

/** A click that places nothing selects the object under the pointer, or nothing on the room or empty space. */
function selectAt(editor, hit) {
  editor.select(hit && !hit.room ? hit.objectId : null);
}

/**
 * Wire the condition's panel and the editor's clicks.
 * ``page``: ``editor``, ``scene``, ``models`` (the library's list), ``trial`` (index), ``api``, ``log``, ``strings``,
 * ``say`` (the banner), ``onEnded`` (the session has ended) and ``onSuggestions(response, hit)`` (each context list).
 */
export function setUpCondition(condition, page) {
  if (condition === "none") listCondition(page);
  else suggestionCondition(page);
}

/** "none": the model chosen from the list waits for a click on a surface. */
function listCondition({ editor, models, api, log, strings }) {
  const hint = $("hint");
  let choice = null;
  const panel = new ModelListPanel($("model-panel"), { models, api, log, strings,
    onChoose: (model, how) => { choice = { model, how }; hint.textContent = strings.placing; } });
  editor.onClick = (e, hit) => {
    if (!(choice && hit)) { selectAt(editor, hit); return; }
    editor.insert(canonical(choice.model, hit), choice.how);
    choice = null;
    panel.clearChoice();
    hint.textContent = "";
  };
}

/** "basic" and "full": context queries on a shift-click or in suggest mode, and the panel of ranked suggestions. */
function suggestionCondition(page) {
  const { editor, api, log, strings } = page;
  let current = null;  // the object placed from the open suggestion list, and where
  let suggestMode = false;
  $("hint").textContent = strings.suggestHint;
  const panel = new SuggestionPanel($("editor"), { api, log, strings, onPick: (s, model, how) => {
    if (!current) return;
    const spec = s ? fromSuggestion(s, model, current.hit) : canonical(model, current.hit);
    current.objectId = editor.replace(current.objectId, spec, how);
  } });
  $("suggest-mode").addEventListener("click", (e) => {
    suggestMode = !suggestMode;
    e.currentTarget.setAttribute("aria-pressed", String(suggestMode));
  });
  editor.onClick = async (e, hit, shift) => {
    if ((shift || suggestMode) && hit) {
      const placed = await suggestAt(page, hit);
      if (placed) {
        current = placed;
        panel.show(placed.response, e.clientX, e.clientY);
        $("hint").textContent = "";  // learnt: the hint goes (it stays under "How to")
      }
      return;
    }
    if (panel.open) { panel.close(); current = null; }
    selectAt(editor, hit);
  };
}

/** Ask for suggestions at ``hit``, log the query and the list, and place the top suggestion; resolves
 * ``{ hit, objectId, response }``, or null when nothing was placed. */
async function suggestAt({ editor, scene, trial, api, log, strings, say, onEnded, onSuggestions = () => {} }, hit) {
  const where = { parent: hit.objectId, point: hit.point.toArray(), normal: hit.normal.toArray() };
  let r;
  try {
    r = await api("/suggest", { method: "POST", body: JSON.stringify({ trial, ...where, scene: scene.objectsJSON() }) });
  } catch (err) { say(strings.suggestOffline, { transient: true }); return null; }
  if (r.status === 410) { onEnded(); return null; }
  if (!r.ok) { say(strings.suggestOffline, { transient: true }); return null; }
  const response = await r.json();
  onSuggestions(response, hit);
  log("context_query", { ...where, list_id: response.list_id });
  log("list_shown", { source: "context", items: response.suggestions.map((s) => s.category), list_id: response.list_id });
  if (!response.suggestions.length) return null;
  const top = response.suggestions[0];
  const how = { source: "context", rank: 1, listId: response.list_id };
  return { hit, response, objectId: editor.insert(fromSuggestion(top, top.models[0], hit), how) };
}
