"""What the server checks when a trial is done, for the experimenter (never shown to the participant): whether
the trial's events rebuild the final scene it submitted (:mod:`scenesuggest.contract.replay`), and how close that scene
came to the target (:mod:`scenesuggest.contract.scoring`), flagging trials below the study's ``[limits]
min_target_score`` for review."""

from __future__ import annotations

import re

from flask import current_app
from sqlalchemy import select
from sqlalchemy.exc import SQLAlchemyError

from scenesuggest.contract.replay import ReplayUnavailable, differences, final_scene
from scenesuggest.contract.scoring import Closeness, closeness
from scenesuggest.scenes import scene_json

from ..base.errors import StudyError
from ..base.extensions import db
from ..base.models import Participant, Trial
from ..participants.flow import SessionEnded, below_target, finish_trial, may_complete, submit_exit, trials
from ..studies.served import StudyRuntime
from .posted_scenes import live_scene
from .replays import trial_events

#: How many differences a mismatch names.
SHOWN = 3
#: How a check waiting for the trial's last events begins (then the seq it waits for).
PENDING = "pending: events up to seq"


class UnknownTrial(StudyError):
    """A trial index that names no trial of the session."""

    def __init__(self, index: int):
        super().__init__(f"trial {index} is not in this session", "trial")


def done(rt: StudyRuntime, p: Participant, index: int, scene: dict | None, last_seq: int | None) -> None:
    """Trial ``index`` of ``p`` is done, with its final ``scene`` as the editor posts it (None: none submitted) and
    ``last_seq`` the seq of the last event the page logged (None: the page does not say): the trial finishes
    (:func:`~study_server.participants.flow.finish_trial`; a retry for a finished trial changes nothing), the checks
    waiting for events that have arrived since are made (:func:`settle`), and the trial just finished is checked
    (:func:`check_trial`). Raises :class:`UnknownTrial`, the flow's refusals and the posted scene's. The caller
    commits."""
    t = db.session.scalar(select(Trial).where(Trial.participant_id == p.id, Trial.index == index))
    if t is None:
        raise UnknownTrial(index)
    final = None if scene is None else scene_json.scene_to_dict(live_scene(scene, rt.scene_type(t.scene_id)))
    finished = finish_trial(p, rt.study, index, final)
    settle(rt, p)
    if finished.replay is None:  # just finished (a retried request finds it checked)
        check_trial(rt, p, finished, last_seq)


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


def _guarded(what: str, t: Trial, check):
    """``check()``, or None after logging when it fails: the experimenter's checks never hold a participant up.
    Database errors are not the check's: they propagate (the request fails as a whole and is retried)."""
    try:
        return check()
    except SQLAlchemyError:
        raise
    except Exception:  # noqa: BLE001 - logged with its traceback; the trial records that the check failed
        current_app.logger.exception("%s of trial %s of participant %s", what, t.index, t.participant_id)
        return None


def _replay(rt: StudyRuntime, t: Trial) -> str:
    found = _guarded("replay check", t, lambda: replay_check(rt, t, trial_events(t.participant_id, t.index)))
    return found if found is not None else "unavailable: the check failed"


def check_trial(rt: StudyRuntime, p: Participant, t: Trial, last_seq: int | None = None) -> None:
    """Record on ``p``'s trial just done whether its events rebuild its final scene, and how close it came to the
    target (the whole result, as the export gives it); below the study's ``min_target_score`` the trial is flagged
    for review. While the server lacks events up to ``last_seq`` (the last the page logged) the check waits
    (``replay_waits_for``) and :func:`settle` makes it later. A check that fails is recorded as unavailable (the
    score: left empty) and logged: the participant goes on. The caller commits."""
    if last_seq is not None and p.acked_seq < last_seq:
        t.replay, t.replay_waits_for = f"{PENDING} {last_seq} not stored yet", last_seq
    else:
        t.replay = _replay(rt, t)
    if t.final_scene is None:
        return
    found = _guarded("score", t, lambda: target_closeness(rt, t.scene_id, t.final_scene["objects"]))
    t.closeness = found.record() if found is not None else {"unavailable": "the check failed"}
    t.score = found.score if found is not None else None
    below = below_target(rt.study, t)
    if below:
        t.review = f"{t.review}; {below}" if t.review else below


def _waiting_in_prose(replay: str | None) -> int | None:
    """The seq a check waits for as an app server of the version before the column wrote it (in ``replay`` only):
    while two versions serve one database during an upgrade, such checks are made too. A rolling upgrade spans
    one version: this reading goes in version 0.2.0, when no app server that writes prose can still be serving."""
    found = re.fullmatch(rf"{PENDING} (\d+) not stored yet", replay or "")
    return int(found.group(1)) if found else None


def settle(rt: StudyRuntime, p: Participant, final: bool = False) -> None:
    """Make the waiting replay checks of ``p``'s trials whose events have all arrived since; ``final`` (at
    completion) makes every waiting check on what is stored, noting the events that never arrived. The caller
    commits."""
    for t in trials(p):
        waits_for = t.replay_waits_for if t.replay_waits_for is not None else _waiting_in_prose(t.replay)
        if waits_for is None:
            continue
        arrived = p.acked_seq >= waits_for
        if arrived or final:
            t.replay = _replay(rt, t) + ("" if arrived else f" (events after seq {p.acked_seq} never arrived)")
            t.replay_waits_for = None


def complete_session(rt: StudyRuntime, p: Participant, answers: dict, last_seq: int, attempt: int) -> bool:
    """The exit survey submitted with ``answers`` (validated), on the page's ``attempt`` to get its events up to
    ``last_seq`` acknowledged: once the server holds them (:func:`~study_server.participants.flow.may_complete`;
    after enough attempts it completes anyway), the waiting replay checks are made on what is stored
    (:func:`settle`) and the session completes (:func:`~study_server.participants.flow.submit_exit`; an exclusion
    committed meanwhile is left as it is). False: not yet — the page flushes its outbox and tries again. The
    caller commits."""
    if not may_complete(p, last_seq, attempt):
        return False
    settle(rt, p, final=True)
    try:
        submit_exit(p, rt.study, answers)
    except SessionEnded:
        db.session.rollback()
    return True
