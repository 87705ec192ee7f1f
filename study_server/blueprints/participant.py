"""Participant pages under /study/<study_id>/: entry, device check, consent, surveys, instructions, trials,
completion. Progress lives on the server; every GET shows the participant's current step, so reloads,
the back button and second tabs resume where they were (logged as ``resume``)."""

from __future__ import annotations

import secrets

from flask import Blueprint, current_app, redirect, render_template, request, send_from_directory, session, url_for
from sqlalchemy import select
from werkzeug.exceptions import HTTPException, NotFound

from .. import assignment, flow, storage
from ..extensions import db
from ..models import Participant, SessionLog, log, utcnow
from ..runtime import runtime
from ..security import check_csrf

bp = Blueprint("participant", __name__, url_prefix="/study/<study_id>")
MTURK_PREVIEW = "ASSIGNMENT_ID_NOT_AVAILABLE"
#: Attempts the exit page makes to get the last events acknowledged before completing anyway.
SAVE_ATTEMPTS = 5


@bp.errorhandler(Exception)
def _friendly(e: Exception):
    """No error page reaches a participant: a calm message, and the failure in the log."""
    if isinstance(e, HTTPException) and e.code and e.code < 500:
        status = e.code
        message = e.description if e.code == 400 else "This page does not exist. Please use the link you were given."
    elif storage.unavailable(e):
        current_app.logger.error("database unavailable: %s", e)
        status = 503
        message = ("We cannot save anything for a moment. Your work is kept in this browser; please wait a "
                   "minute and reload this page.")
    else:
        current_app.logger.exception("participant page failure")
        status = 500
        message = "Something went wrong on our side. Your work is saved; please reload this page in a moment."
    db.session.rollback()
    reference = secrets.token_hex(4)
    try:
        log("error", None, study_id=request.view_args.get("study_id") if request.view_args else None,
            reference=reference, path=request.path, status=status, error=type(e).__name__)
        db.session.commit()
    except Exception:  # the database itself may be what failed
        db.session.rollback()
    return render_template("message.html", title="Sorry", message=message, reference=reference), status


def _participant(study_id: str) -> Participant | None:
    token = (session.get("participants") or {}).get(study_id)
    if not token:
        return None
    return db.session.scalar(select(Participant).where(Participant.token == token))


def _remember(study_id: str, p: Participant) -> None:
    tokens = dict(session.get("participants") or {})
    tokens[study_id] = p.token
    session["participants"] = tokens
    session.permanent = True


def _platform_identity(study, args) -> tuple[str, dict] | None:
    """(platform id, platform metadata) from the entry URL's parameters, or None when they are missing."""
    if study.platform == "prolific":
        meta = {k: args.get(k, "")[:128] for k in ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID")}
        return (meta["PROLIFIC_PID"], meta) if meta["PROLIFIC_PID"] else None
    if study.platform == "mturk":
        meta = {k: args.get(k, "")[:256] for k in ("workerId", "assignmentId", "hitId", "turkSubmitTo")}
        return (meta["workerId"], meta) if meta["workerId"] else None
    pid = args.get("pid", "")[:128]
    return (pid, {"pid": pid}) if pid else ("", {})


@bp.get("/start")
def start(study_id: str):
    rt = runtime(study_id)
    study = rt.study
    if study.platform == "mturk" and request.args.get("assignmentId") == MTURK_PREVIEW:
        return render_template("mturk_preview.html", study=study)
    identity = _platform_identity(study, request.args)
    if identity is None:
        return render_template("message.html", title=study.title,
                               message="Please open this study from the link on your crowdsourcing platform."), 400
    platform_id, meta = identity
    mine = _participant(study_id)
    if mine is not None and (not platform_id or mine.platform_id == platform_id):
        log("resume", mine, via="entry link")
        db.session.commit()
        return redirect(url_for(".current", study_id=study_id))
    if not platform_id:  # an anonymous link: a new id, remembered by this browser
        platform_id = "link-" + secrets.token_hex(8)
    p, created = assignment.arrive(study, study.platform, platform_id, meta, request.headers.get("User-Agent", ""))
    if not created:
        log("resume", p, via="platform id")
        db.session.commit()
    _remember(study_id, p)
    return redirect(url_for(".current", study_id=study_id))


def _log_view(p: Participant) -> None:
    """A view of the same place as the last one is a resume (reload, back button, second tab)."""
    where = {"step": p.step, "position": p.position, "page": p.instruction_page}
    last = db.session.scalar(select(SessionLog).where(SessionLog.participant_id == p.id,
                                                      SessionLog.kind.in_(("view", "resume")))
                             .order_by(SessionLog.id.desc()).limit(1))
    log("resume" if last is not None and last.detail.get("where") == where else "view", p, where=where)


@bp.get("/")
def current(study_id: str):
    rt = runtime(study_id)
    study = rt.study
    p = _participant(study_id)
    if p is None:
        return render_template("message.html", title=study.title,
                               message="Please start this study from the link you were given."), 200
    flow.check_session_time(p, study)
    p.last_seen_at = utcnow()
    _log_view(p)
    db.session.commit()
    context = {"study": study, "p": p}
    if p.step == "device":
        return render_template("device.html", **context)
    if p.step == "consent":
        return render_template("consent.html", **context)
    if p.step == "demographics":
        return render_template("survey.html", survey="demographics", questions=study.demographics, errors={},
                               answers={}, action=url_for(".demographics", study_id=study_id),
                               heading="About you", **context)
    if p.step == "instructions":
        title, body = study.instructions[p.instruction_page]
        return render_template("instructions.html", title=title, body=body, page=p.instruction_page,
                               pages=len(study.instructions), **context)
    if p.step == "trial":
        return _trial_page(rt, p)
    if p.step == "exit":
        return render_template("survey.html", survey="exit", questions=study.exit_survey, errors={}, answers={},
                               action=url_for(".exit_survey", study_id=study_id), heading="Almost done",
                               **context)
    return render_template("done.html", completion_url=flow.completion_url(study, p), **context)


def _trial_page(rt, p: Participant):
    t = flow.start_trial(p)
    db.session.commit()
    plan = [x for x in flow.trials(p) if x.kind == "trial"]
    condition = rt.study.condition(t.condition)
    boot = {"study": p.study_id, "token": p.token, "preview": False, "trial": {
        "index": t.index, "kind": t.kind, "condition": t.condition, "scene": t.scene_id, "block": t.block,
        "number": t.index + 1, "of": len(plan)}, "page_id": secrets.token_hex(8),
        "api": url_for("api.session_state").rsplit("/", 1)[0], "next": url_for(".current", study_id=p.study_id),
        "limits": {"trial_minutes": rt.study.trial_minutes}}
    return render_template("trial.html", study=rt.study, p=p, trial=t, condition=condition,
                           boot=boot, scene_title=rt.study.scenes[t.scene_id].title)


def _post_participant(study_id: str) -> Participant:
    check_csrf()
    p = _participant(study_id)
    if p is None:
        raise NotFound()
    p.last_seen_at = utcnow()
    return p


@bp.post("/device")
def device(study_id: str):
    study = runtime(study_id).study
    p = _post_participant(study_id)
    if p.step == "device":
        flow.check_device(p, study, request.form)
    db.session.commit()
    return redirect(url_for(".current", study_id=study_id))


@bp.post("/consent")
def consent(study_id: str):
    study = runtime(study_id).study
    p = _post_participant(study_id)
    if p.step == "consent":
        flow.give_consent(p, study, request.form.get("agree") == "yes")
    db.session.commit()
    return redirect(url_for(".current", study_id=study_id))


def _survey(study_id: str, name: str, questions, submit, heading: str):
    study = runtime(study_id).study
    p = _post_participant(study_id)
    if p.step != name:
        db.session.commit()
        return redirect(url_for(".current", study_id=study_id))
    answers, errors = flow.validate_answers(questions, request.form)
    if errors:
        db.session.commit()
        return render_template("survey.html", survey=name, questions=questions, errors=errors, answers=request.form,
                               action=request.path, heading=heading, study=study, p=p), 422
    return submit(p, study, answers)


@bp.post("/demographics")
def demographics(study_id: str):
    def submit(p, study, answers):
        flow.submit_demographics(p, study, answers)
        db.session.commit()
        return redirect(url_for(".current", study_id=study_id))
    return _survey(study_id, "demographics", runtime(study_id).study.demographics, submit, "About you")


@bp.post("/instructions")
def instructions(study_id: str):
    study = runtime(study_id).study
    p = _post_participant(study_id)
    if p.step == "instructions":
        flow.turn_instructions(p, study, request.form.get("go", "next"))
    db.session.commit()
    return redirect(url_for(".current", study_id=study_id))


@bp.post("/exit")
def exit_survey(study_id: str):
    def submit(p, study, answers):
        try:
            last_seq = int(request.form.get("last_seq", "-1"))
            attempt = int(request.form.get("attempt", "0"))
        except ValueError:
            last_seq, attempt = -1, SAVE_ATTEMPTS
        if p.acked_seq < last_seq and attempt < SAVE_ATTEMPTS:
            # the final events are not acknowledged yet: let the page flush its outbox and try again
            db.session.commit()
            return render_template("saving.html", study=study, p=p, answers=answers, attempt=attempt + 1,
                                   last_seq=last_seq), 202
        if p.acked_seq < last_seq:  # documented fallback: the network is gone, complete anyway
            log("completed_with_missing_events", p, acked_seq=p.acked_seq, last_seq=last_seq)
        flow.submit_exit(p, study, answers)
        db.session.commit()
        return redirect(url_for(".current", study_id=study_id))
    return _survey(study_id, "exit", runtime(study_id).study.exit_survey, submit, "Almost done")


@bp.get("/assets/<path:filename>")
def asset(study_id: str, filename: str):
    """GLB models and thumbnails of the study's library (public, long-cached; no path escapes the library)."""
    rt = runtime(study_id)
    if not (filename.startswith("models/") or filename.startswith("thumbnails/")):
        raise NotFound()
    response = send_from_directory(rt.study.library, filename, max_age=7 * 24 * 3600)
    response.headers["Cache-Control"] = "public, max-age=604800, immutable"
    return response
