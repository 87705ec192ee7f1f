"""Participant pages under /study/<study_id>/: entry, device check, consent, surveys, instructions, trials,
completion. Progress lives on the server; every GET shows the participant's current step, so reloads,
the back button and second tabs resume where they were (logged as ``resume``)."""

from __future__ import annotations

import posixpath
import re

from flask import (
    Blueprint,
    current_app,
    g,
    redirect,
    render_template,
    request,
    send_from_directory,
    session,
    url_for,
)
from flask_babel import gettext as _
from sqlalchemy import select
from werkzeug.exceptions import NotFound

from ..base import i18n
from ..base.extensions import db
from ..base.models import Participant
from ..base.security import address_key, check_csrf
from ..participants import arrival, flow
from ..participants import device as device_check
from ..participants.boot import trial_boot
from ..studies.served import runtime
from ..trials import trial_check

bp = Blueprint("participant", __name__, url_prefix="/study/<study_id>")


@bp.before_request
def _language() -> None:
    """The language of the page: the participant's (chosen at arrival), else the one this browser would get."""
    study_id = (request.view_args or {}).get("study_id")
    studies = current_app.extensions["studies"]
    if study_id not in studies:
        return
    study = studies[study_id].study
    g.language = i18n.choose(study, request.accept_languages)  # first: a database that fails still has a page
    p = _participant(study_id)
    if p is not None and p.language in study.languages:  # (a language the study no longer speaks: the browser's)
        g.language = p.language


def _participant(study_id: str) -> Participant | None:
    """The participant this browser's cookie names in ``study_id``: read once per request (the page's language
    needs it before the view does)."""
    token = (session.get("participants") or {}).get(study_id)
    if not token:
        return None
    known = g.setdefault("participants", {})
    if token not in known:
        known[token] = db.session.scalar(select(Participant).where(Participant.token == token))
    return known[token]


def _remember(study_id: str, p: Participant) -> None:
    tokens = dict(session.get("participants") or {})
    tokens[study_id] = p.token
    session["participants"] = tokens
    session.permanent = True


def _entry_page(study, message: str, status: int):
    return render_template("message.html", title=study.title, message=message), status


@bp.get("/start")
def start(study_id: str):
    study = runtime(study_id).study
    if arrival.is_preview(study, request.args):
        return render_template("mturk_preview.html", study=study)
    try:
        p = arrival.enter(study, request.args, _participant(study_id), request.headers.get("User-Agent", ""),
                          address_key(), i18n.choose(study, request.accept_languages), current_app.config["SECRET_KEY"])
    except arrival.EntryRefused as e:  # the entry page, with the study's title
        return _entry_page(study, e.message, e.status)
    _remember(study_id, p)
    return redirect(url_for(".current", study_id=study_id))


@bp.get("/")
def current(study_id: str):
    rt = runtime(study_id)
    study = rt.study
    p = _participant(study_id)
    if p is None:
        return render_template("message.html", title=study.title,
                               message=_("Please start this study from the link you were given.")), 200
    flow.visit(p, study)
    # the page is made before the commit (which would expire what it reads) and its writes wait for the commit
    # (SQLite's write lock, taken by the first, is held until then)
    with db.session.no_autoflush:
        page = _page(rt, p)
    db.session.commit()
    return page


def _page(rt, p: Participant):
    """The page of the participant's current step (a trial's starts it)."""
    study, study_id = rt.study, p.study_id
    context = {"study": study, "p": p}
    if not flow.is_open(p):  # finished, declined, screened out or excluded: only the end page
        return _end_page(study, p, context)
    if p.step == "device":
        return render_template("device.html", **context)
    if p.step == "consent":
        return render_template("consent.html", **context)
    if p.step == "demographics":
        return render_template("survey.html", survey="demographics", questions=study.demographics, errors={},
                               answers={}, action=url_for(".demographics", study_id=study_id),
                               heading=_("About you"), **context)
    if p.step == "instructions":
        title, body = study.instructions[p.instruction_page]
        return render_template("instructions.html", title=title, body=body, page=p.instruction_page,
                               pages=len(study.instructions), **context)
    if p.step == "trial":
        return _trial_page(rt, p)
    if p.step == "exit":
        return render_template("survey.html", survey="exit", questions=study.exit_survey, errors={}, answers={},
                               action=url_for(".exit_survey", study_id=study_id), heading=_("Almost done"),
                               **context)
    return _end_page(study, p, context)


def _end_page(study, p: Participant, context: dict):
    """The end page: the code and the way back to the platform; for a browser the device check screened out, what
    it lacks, in the participant's language."""
    report = p.viewport or {}
    reasons = [device_check.reason_text(code, study, report) for code in report.get("reasons", ())
               if p.status == "screened_out"]
    return render_template("done.html", completion_url=flow.completion_url(study, p), screen_reasons=reasons,
                           **context)


def _trial_page(rt, p: Participant):
    """The current trial's page, or before it the page of its condition's instructions when they are due."""
    shown = flow.open_trial(p)
    t = shown.trial
    condition = rt.study.condition(t.condition)
    if shown.briefing:
        return render_template("briefing.html", study=rt.study, p=p, trial=t, condition=condition,
                               first=t.position == 0, of=shown.of)
    seconds = shown.briefing_seconds
    boot = trial_boot(rt.study, p.token, {**t.describe(), "number": t.index + 1, "of": shown.of,
                                          "briefing": None if seconds is None else round(seconds, 3)},
                      url_for(".current", study_id=p.study_id))
    return render_template("trial.html", study=rt.study, p=p, trial=t, condition=condition,
                           boot=boot, scene_title=rt.study.scenes[t.scene_id].title)


def _unless_ended(step, p: Participant, *args) -> None:
    """Run a step that may end the session; when an exclusion committed meanwhile, change nothing."""
    try:
        step(p, *args)
    except flow.SessionEnded:
        db.session.rollback()


def _post_participant(study_id: str) -> Participant | None:
    """The posting participant, or None when their session has ended (the caller shows the end page)."""
    check_csrf()
    p = _participant(study_id)
    if p is None:
        raise NotFound()
    return p if flow.takes_posts(p, request.path) else None


@bp.post("/device")
def device(study_id: str):
    study = runtime(study_id).study
    check_csrf()
    report = device_check.parse_report(request.form)  # a report no browser sends: 422 naming the field, nothing stored
    p = _post_participant(study_id)
    if p is not None and p.step == "device":
        _unless_ended(flow.check_device, p, study, report)
    db.session.commit()
    return redirect(url_for(".current", study_id=study_id))


@bp.get("/leave")
def leave_page(study_id: str):
    """Asks whether to leave the study (a link on every page of a session in progress)."""
    study = runtime(study_id).study
    p = _participant(study_id)
    if p is None or not flow.is_open(p):
        return redirect(url_for(".current", study_id=study_id))
    return render_template("leave.html", study=study, p=p)


@bp.post("/leave")
def leave(study_id: str):
    """Leave the study: the end page then gives the code for it and the way back to the platform."""
    study = runtime(study_id).study
    p = _post_participant(study_id)
    if p is not None:
        _unless_ended(flow.leave, p, study)
    db.session.commit()
    return redirect(url_for(".current", study_id=study_id))


@bp.post("/consent")
def consent(study_id: str):
    study = runtime(study_id).study
    p = _post_participant(study_id)
    if p is not None:
        flow.answer_consent(p, study, request.form.get("agree") == "yes")
    db.session.commit()
    return redirect(url_for(".current", study_id=study_id))


def _survey(study_id: str, name: str, questions, submit, heading: str):
    study = runtime(study_id).study
    p = _post_participant(study_id)
    if p is None or p.step != name:
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
    return _survey(study_id, "demographics", runtime(study_id).study.demographics, submit, _("About you"))


@bp.post("/instructions")
def instructions(study_id: str):
    study = runtime(study_id).study
    p = _post_participant(study_id)
    if p is not None and p.step == "instructions":
        flow.turn_instructions(p, study, request.form.get("go", "next"))
    db.session.commit()
    return redirect(url_for(".current", study_id=study_id))


@bp.post("/briefing")
def briefing(study_id: str):
    """The participant dismissed the instructions of the next trial's condition: the trial starts."""
    p = _post_participant(study_id)
    if p is not None and p.step == "trial":
        position = request.form.get("position", "")
        flow.finish_briefing(p, int(position) if re.fullmatch(r"[0-9]{1,8}", position) else None)
    db.session.commit()
    return redirect(url_for(".current", study_id=study_id))


@bp.post("/exit")
def exit_survey(study_id: str):
    def submit(p, study, answers):
        try:
            last_seq = int(request.form.get("last_seq", "-1"))
            attempt = int(request.form.get("attempt", "0"))
        except ValueError:
            last_seq, attempt = -1, flow.SAVE_ATTEMPTS
        done = trial_check.complete_session(runtime(study_id), p, answers, last_seq, attempt)
        db.session.commit()
        if not done:  # the final events are not acknowledged yet: the page flushes its outbox and tries again
            return render_template("saving.html", study=study, p=p, answers=answers, attempt=attempt + 1,
                                   last_seq=last_seq), 202
        return redirect(url_for(".current", study_id=study_id))
    return _survey(study_id, "exit", runtime(study_id).study.exit_survey, submit, _("Almost done"))


@bp.get("/assets/<path:filename>")
def asset(study_id: str, filename: str):
    """GLB models and thumbnails of the study's library (public, long-cached; no path escapes the library)."""
    rt = runtime(study_id)
    filename = posixpath.normpath(filename)  # the folder check after normalising: models/../x is x
    if not (filename.startswith("models/") or filename.startswith("thumbnails/")):
        raise NotFound()
    response = send_from_directory(rt.study.library, filename, max_age=7 * 24 * 3600)
    response.headers["Cache-Control"] = "public, max-age=604800, immutable"
    return response
