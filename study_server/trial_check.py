"""What the server checks when a trial is done, for the experimenter (never shown to the participant): whether
the trial's events rebuild the final scene it submitted (:mod:`scenesuggest.replay`), and how close that scene
came to the target (:mod:`scenesuggest.scoring`), flagging trials below the study's ``[limits] min_target_score``
for review."""

from __future__ import annotations

from scenesuggest.replay import ReplayUnavailable, differences, final_scene
from scenesuggest.scoring import Closeness, closeness

from .models import Trial
from .replays import trial_events
from .studies import StudyRuntime

#: How many differences a mismatch names.
SHOWN = 3


def replay_check(rt: StudyRuntime, t: Trial, events: list[dict]) -> str:
    """``match``, ``mismatch: …`` (the first differences) or ``unavailable: …``."""
    if t.final_scene is None:
        return "unavailable: no final scene was submitted"
    try:
        rebuilt = final_scene(rt.scene(t.scene_id, "start")["objects"], events)
    except ReplayUnavailable as e:
        return f"unavailable: {e}"
    found = differences(rebuilt, t.final_scene["objects"])
    if not found:
        return "match"
    return "mismatch: " + "; ".join(found[:SHOWN]) + (f" (+{len(found) - SHOWN} more)" if len(found) > SHOWN else "")


def target_closeness(rt: StudyRuntime, scene_id: str, objects: list[dict]) -> Closeness:
    """How close ``objects`` (a final scene's) came to the scene's target."""
    start = {o["id"] for o in rt.scene(scene_id, "start")["objects"]}
    return closeness(objects, rt.scene(scene_id, "target")["objects"], start, rt.taxonomy.parent, rt.period_of)


def check_trial(rt: StudyRuntime, t: Trial) -> None:
    """Record on a trial just done whether its events rebuild its final scene, and its score; below the study's
    ``min_target_score`` the trial is flagged for review. The caller commits."""
    t.replay = replay_check(rt, t, trial_events(t.participant_id, t.index))
    if t.final_scene is None:
        return
    t.score = target_closeness(rt, t.scene_id, t.final_scene["objects"]).score
    least = rt.study.min_target_score
    if least is not None and t.kind == "trial" and t.score < least:
        reason = f"scene {t.score:.2f} close to the target < {least:g}"
        t.review = f"{t.review}; {reason}" if t.review else reason
