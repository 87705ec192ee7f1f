"""Participant pages under /study/<study_id>/: entry, device check, consent, surveys, instructions, trials,
completion. Progress lives on the server; every GET shows the participant's current step, so reloads,
the back button and second tabs resume where they were (logged as ``resume``)."""

from __future__ import annotations

import hmac
import posixpath
import re
import secrets
import unicodedata

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
from ..base.models import Participant, SessionLog, flag, log, log_again, utcnow
from ..base.security import address_key, check_csrf
from ..participants import assignment, flow, pilots
from ..participants import device as device_check
from ..participants.boot import trial_boot
from ..studies.served import runtime
from ..trials import trial_check

bp = Blueprint("participant", __name__, url_prefix="/study/<study_id>")
MTURK_PREVIEW = "ASSIGNMENT_ID_NOT_AVAILABLE"


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


#: Ids as the platforms issue them: Prolific's are 24 hex digits, MTurk's upper-case letters and digits.
PROLIFIC_ID = re.compile(r"[0-9a-fA-F]{24}")
MTURK_ID = re.compile(r"[A-Z0-9]{10,64}")
#: The only hosts an MTurk HIT may be submitted to (``turkSubmitTo``).
MTURK_SUBMIT = ("https://www.mturk.com", "https://workersandbox.mturk.com")
#: A plain link's ``pid``: up to LINK_ID_MAX visible characters — no control or format character (bidi overrides,
#: zero-width spaces, byte-order marks), line or paragraph separator, surrogate, private-use or unassigned code
#: point, any of which would let one id read as another on the admin pages and in the export.
LINK_ID_MAX = 128
INVISIBLE = frozenset(("Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp"))
#: Code points Unicode says to ignore in display that are not of those categories (Hangul fillers, the combining
#: grapheme joiner, Mongolian and standard variation selectors).
IGNORABLE = re.compile("[\u034f\u115f\u1160\u17b4\u17b5\u180b-\u180f\u3164\ufe00-\ufe0f\uffa0"
                       "\U000e0100-\U000e01ef]")


def link_id(value: str) -> bool:
    """Whether ``value`` may be a plain link's ``pid`` (see INVISIBLE and IGNORABLE), written in Unicode's composed
    form (NFC: an id that looks like another is that other)."""
    return (0 < len(value) <= LINK_ID_MAX and not any(unicodedata.category(c) in INVISIBLE for c in value)
            and not IGNORABLE.search(value) and unicodedata.normalize("NFC", value) == value)


class EntryError(Exception):
    """An entry link whose parameters this study cannot accept; the message names the parameter."""


def _platform_identity(study, args) -> tuple[str, dict]:
    """(platform id, platform metadata) from the entry URL's parameters ("" for an anonymous link); raises
    :class:`EntryError` naming a missing or malformed parameter."""
    def value(name: str, valid, required: bool = True) -> str:
        v = args.get(name, "")
        if not v and not required:
            return ""
        if not valid(v):
            raise EntryError(_("%(name)s is missing", name=name) if not v
                             else _("%(name)s is not a valid %(platform)s id", name=name, platform=study.platform))
        return v

    if study.platform == "prolific":
        meta = {"PROLIFIC_PID": value("PROLIFIC_PID", PROLIFIC_ID.fullmatch),
                "STUDY_ID": value("STUDY_ID", PROLIFIC_ID.fullmatch, required=bool(study.platform_study_id)),
                "SESSION_ID": value("SESSION_ID", PROLIFIC_ID.fullmatch, required=False)}
        if study.platform_study_id and meta["STUDY_ID"] != study.platform_study_id:
            raise EntryError(_("STUDY_ID is not this study's Prolific id"))
        return meta["PROLIFIC_PID"], meta
    if study.platform == "mturk":
        meta = {k: value(k, MTURK_ID.fullmatch) for k in ("workerId", "assignmentId", "hitId")}
        submit = args.get("turkSubmitTo", "").rstrip("/")
        if submit not in MTURK_SUBMIT:
            raise EntryError(_("turkSubmitTo is not one of MTurk's submit hosts"))
        meta["turkSubmitTo"] = submit
        return meta["workerId"], meta
    pid = value("pid", link_id, required=False)
    return pid, ({"pid": pid} if pid else {})


def _pilot(study, platform_id: str, args) -> bool:
    """Whether the entry link is a pilot's (signed with the server's key: study_server.participants.pilots); a ``pilot``
    parameter that is not this id's signature is refused (:class:`EntryError`), never taken for a participant's."""
    given = args.get(pilots.PARAM)
    if given is None:
        return False
    if not platform_id or not pilots.is_pilot(current_app.config["SECRET_KEY"], study.id, platform_id, given):
        raise EntryError(_("%(name)s is not a test link of this study", name=pilots.PARAM))
    return True


def _proves(p: Participant, meta: dict) -> bool:
    """Whether an entry link carries what only this participant's platform session has: Prolific's
    SESSION_ID or MTurk's assignmentId, as first seen. A bare id (or a plain link's pid) proves nothing."""
    key = {"prolific": "SESSION_ID", "mturk": "assignmentId"}.get(p.platform)
    mine = (p.platform_meta or {}).get(key) if key else None
    return bool(mine) and hmac.compare_digest(str(mine).encode(), (meta.get(key) or "").encode())


def _entry_page(study, message: str, status: int):
    return render_template("message.html", title=study.title, message=message), status


@bp.get("/start")
def start(study_id: str):
    rt = runtime(study_id)
    study = rt.study
    if study.platform == "mturk" and request.args.get("assignmentId") == MTURK_PREVIEW:
        return render_template("mturk_preview.html", study=study)
    try:
        platform_id, meta = _platform_identity(study, request.args)
        pilot = _pilot(study, platform_id, request.args)
    except EntryError as e:  # the application log, not the database: anyone can send these
        current_app.logger.info("entry refused for study %s: %s", study_id, e)
        return _entry_page(study, _("This link cannot start the study: %(problem)s. Please open the study from the "
                                    "link on your crowdsourcing platform.", problem=str(e)), 422)
    if study.platform != "link" and not platform_id:
        return _entry_page(study, _("Please open this study from the link on your crowdsourcing platform."), 400)
    mine = _participant(study_id)
    if mine is not None and (not platform_id or mine.platform_id == platform_id):
        log_again("resume", mine, via="entry link")
        db.session.commit()
        return redirect(url_for(".current", study_id=study_id))
    if not platform_id:  # an anonymous link: a new id, remembered by this browser
        platform_id = "link-" + secrets.token_hex(8)
    try:
        p, created = assignment.arrive(study, study.platform, platform_id, meta,
                                       request.headers.get("User-Agent", ""), address_key(),
                                       language=i18n.choose(study, request.accept_languages), pilot=pilot)
    except assignment.QuotaExceeded:
        current_app.logger.warning("arrival quota reached for an address in study %s", study_id)
        return _entry_page(study, _("Too many people have started this study from your network in the last hour. "
                                    "Please try again later."), 429)
    if created and mine is not None and not (pilot or mine.pilot):  # one browser, a second id: flag both
        reason = (f"this browser already took part as participant {mine.id} ({mine.status}, id "
                  f"{mine.platform_id[:40]!r})")
        flag(p, reason)
        flag(mine, f"this browser came back as participant {p.id} under another id")
        db.session.commit()
    elif not created:  # the id has a session already (begun in another browser, or a moment ago in another tab)
        return _resume_elsewhere(study, p, meta)
    _remember(study_id, p)
    return redirect(url_for(".current", study_id=study_id))


def _resume_elsewhere(study, existing: Participant, meta: dict):
    """A browser without this participant's cookie: it resumes only with the platform's session id."""
    if not _proves(existing, meta):  # someone else's id, or the participant in a new browser: never a takeover
        flag(existing, "the study was opened with this participant's id in another browser without the "
                       "platform's session id (refused)", by=address_key())
        db.session.commit()
        return _entry_page(study, _("This study is already in progress in another browser. Please continue there; "
                                    "if you cannot, contact the researcher through your platform."), 409)
    log("resume", existing, via="platform session")
    db.session.commit()
    _remember(study.id, existing)
    return redirect(url_for(".current", study_id=study.id))


def _log_view(p: Participant) -> None:
    """A view of the same place as the last one is a resume (reload, back button, second tab)."""
    where = {"step": p.step, "position": p.position, "page": p.instruction_page}
    last = db.session.scalar(select(SessionLog).where(SessionLog.participant_id == p.id,
                                                      SessionLog.kind.in_(("view", "resume")))
                             .order_by(SessionLog.id.desc()).limit(1))
    if last is not None and last.detail.get("where") == where:
        log_again("resume", p, where=where)  # reloads count on one row
    else:
        log("view", p, where=where)


@bp.get("/")
def current(study_id: str):
    rt = runtime(study_id)
    study = rt.study
    p = _participant(study_id)
    if p is None:
        return render_template("message.html", title=study.title,
                               message=_("Please start this study from the link you were given.")), 200
    flow.check_session_time(p, study)
    _log_view(p)
    p.last_seen_at = utcnow()
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
    everything = flow.trials(p)  # in order: a trial's position is its place here
    t = everything[p.position]
    plan = [x for x in everything if x.kind == "trial"]
    condition = rt.study.condition(t.condition)
    if flow.briefing_due(p, t, everything):
        flow.show_briefing(p, t)
        return render_template("briefing.html", study=rt.study, p=p, trial=t, condition=condition,
                               first=t.position == 0, of=len(plan))
    flow.start_trial(p, t)
    seconds = flow.briefing_seconds(t)
    boot = trial_boot(rt.study, p.token, {"index": t.index, "kind": t.kind, "condition": t.condition,
                                          "scene": t.scene_id, "block": t.block, "number": t.index + 1,
                                          "of": len(plan),
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
    if not flow.is_open(p):
        log_again("refused", p, path=request.path, status=p.status)
        db.session.commit()
        return None
    p.last_seen_at = utcnow()
    return p


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
    if p is not None and p.step == "consent":
        agree = request.form.get("agree") == "yes"
        if agree:
            assignment.assign(study, p)  # a schedule row and trials only now (commits; p is fresh after it)
        if p.step == "consent" and flow.is_open(p):  # another tab may have moved on meanwhile
            _unless_ended(flow.give_consent, p, study, agree)
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
        if not flow.may_complete(p, last_seq, attempt):
            # the final events are not acknowledged yet: let the page flush its outbox and try again
            db.session.commit()
            return render_template("saving.html", study=study, p=p, answers=answers, attempt=attempt + 1,
                                   last_seq=last_seq), 202
        trial_check.settle(runtime(study_id), p, final=True)  # the pending replay checks, made now
        _unless_ended(flow.submit_exit, p, study, answers)
        db.session.commit()
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
