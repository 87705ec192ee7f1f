"""A trial as its events rebuild it (:mod:`scenesuggest.contract.replay`): for the check when it is done and for the
admin's replay, which shows any trial, finished or in progress, step by step."""

from __future__ import annotations

from flask import url_for
from sqlalchemy import select

from scenesuggest.contract.events import SCENE_CHANGES, as_event
from scenesuggest.contract.replay import ReplayUnavailable, apply, final_scene, start_scene

from ..base.extensions import db
from ..base.models import Event, Trial
from ..studies.served import StudyRuntime

#: The most object states a replay document carries (the start scene, then the states each step changes): a bound
#: on its size whatever the trial did.
MAX_SHOWN_STATES = 200_000


def trial_events(participant_id: int, index: int) -> list[dict]:
    """A trial's stored events, in seq order, as the replay reads them."""
    rows = db.session.scalars(select(Event).where(Event.participant_id == participant_id, Event.trial == index)
                              .order_by(Event.seq))
    return [as_event(e.seq, e.client_t, e.type, e.trial, e.payload) for e in rows]


def progress(rt: StudyRuntime, p, scene_id: str) -> dict:
    """The participant's current trial, when it is on ``scene_id``, as far as its stored events rebuild it: the
    start scene's document with the rebuilt ``objects``, ``changes`` (its scene-changing events; 0: nothing to
    restore) and ``last_change_seq`` (the seq of the last of them, −1: none). What a page in a browser that kept
    no copy of the scene (another browser, a cleared storage) starts from."""
    doc = rt.scene(scene_id, "start")
    t = db.session.scalar(select(Trial).where(Trial.participant_id == p.id, Trial.position == p.position,
                                              Trial.scene_id == scene_id))  # the current trial, if on this scene
    events = [e for e in trial_events(p.id, t.index) if e["type"] in SCENE_CHANGES] if t is not None else []
    try:
        rebuilt = final_scene(doc["objects"], events)
    except ReplayUnavailable:  # events of vocabulary 1 carry no states: nothing to restore from
        events, rebuilt = [], start_scene(doc["objects"])
    return {**doc, "objects": list(rebuilt.values()), "changes": len(events),
            "last_change_seq": events[-1]["seq"] if events else -1}


def label(event: dict) -> str:
    """One line of the admin's event list."""
    p, kind = event["payload"], event["type"]
    if kind in ("insert", "replace"):
        rank = f", rank {p['rank']}" if p.get("rank") else ""
        return f"{kind} {p.get('object')} ({p.get('category')}{rank}, {p.get('source')})"
    if kind == "move_end":
        return f"moved {p.get('object')} {p.get('distance', 0):.2f} m"
    if kind == "rotate_end":
        return f"turned {p.get('object')} {p.get('angle', 0):+.0f}°"
    if kind in ("delete", "select"):
        return f"{kind} {p.get('object') or 'nothing'}"
    if kind in ("undo", "redo"):
        return f"{kind} ({p.get('action')})"
    if kind == "search":
        return f"search “{p.get('text', '')}”"
    if kind == "list_shown":
        return f"{p.get('source')} list shown ({len(p.get('items', []))})"
    if kind == "camera":
        return f"camera {p.get('action')}"
    if kind == "briefing":
        return f"read the instructions of {p.get('condition')} ({p.get('seconds', 0):.0f} s, before the trial)"
    return kind.replace("_", " ")


def step(before: dict, after: dict) -> dict:
    """What changed from one scene to the next (object id → state): the states set (added or changed) and the ids
    taken away. A step carries what an event changed, not the whole scene again."""
    return {"set": [state for oid, state in after.items() if before.get(oid) != state],
            "removed": [oid for oid in before if oid not in after]}


def replay_document(rt: StudyRuntime, t: Trial) -> dict:
    """What the replay page shows: the trial, its start and target, the models, every event (client time, a
    label, and ``scene``: how many steps of ``steps`` rebuild the scene after it from ``start``). Scene ``k`` is
    ``start`` with steps 1…k applied in order (:func:`step`), as the page rebuilds it; its size grows with what
    the events changed, not with the scene's size times the number of changes."""
    start = rt.scene(t.scene_id, "start")["objects"]
    events = trial_events(t.participant_id, t.index)
    doc = {"trial": {"participant": t.participant_id, **t.describe(), "title": rt.study.scenes[t.scene_id].title,
                     "done": t.done_at is not None, "replay": t.replay, "score": t.score},
           "target": rt.scene(t.scene_id, "target")["objects"], "start": start, "steps": [], "events": [],
           "problem": None}
    scene, shown, used = start_scene(start), len(start), {o["model_id"] for o in start}
    for e in events:
        if doc["problem"] is None:
            try:
                after = apply(scene, e)
            except ReplayUnavailable as problem:
                doc["problem"] = f"this trial cannot be replayed from seq {e['seq']} on: {problem}"
            else:
                if after is not scene:
                    change = step(scene, after)
                    shown += len(change["set"]) + len(change["removed"])
                    if shown > MAX_SHOWN_STATES:
                        doc["problem"] = (f"this trial changed its scene too often to show every step here (more "
                                          f"than {MAX_SHOWN_STATES} object states); the steps stop at seq "
                                          f"{e['seq']}")
                    else:
                        doc["steps"].append(change)
                        used.update(o["model_id"] for o in change["set"])
                        scene = after
        doc["events"].append({"seq": e["seq"], "t": e["t"], "type": e["type"], "label": label(e),
                              "scene": len(doc["steps"])})
    used |= {o["model_id"] for o in doc["target"]}
    doc["models"] = [{"id": m.id, "name": m.name, "category": m.category, "size": list(m.size),
                      "asset": url_for("participant.asset", study_id=rt.study.id, filename=m.asset)}
                     for m in rt.library.values() if m.id in used]
    return doc


def scene_after(doc: dict, index: int) -> list[dict]:
    """Scene ``index`` of a replay document (``start`` with its first ``index`` steps applied), as the replay page
    rebuilds it."""
    scene = {o["id"]: o for o in doc["start"]}
    for change in doc["steps"][:index]:
        for oid in change["removed"]:
            scene.pop(oid, None)
        scene.update((o["id"], o) for o in change["set"])
    return list(scene.values())
