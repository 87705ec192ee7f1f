"""Admin pages under /admin/: login, live progress, participant timelines, exclusion, previews, export."""

from __future__ import annotations

import json
import re

from flask import (
    Blueprint,
    Response,
    abort,
    current_app,
    jsonify,
    redirect,
    render_template,
    request,
    send_file,
    stream_with_context,
    url_for,
)
from sqlalchemy import select

from scenesuggest.contract.events import MAX_SEQ

from ..base.errors import RequestError
from ..base.extensions import db
from ..base.models import Event, Participant, SessionLog, SurveyResponse, Trial, utcnow
from ..base.security import (
    DEVICE_COOKIE,
    DEVICE_LIFETIME,
    LoginBlocked,
    admin_link_live,
    admin_required,
    attempt_login,
    check_csrf,
    csrf_ok,
    csrf_token,
    end_admin_session,
    preview_token,
    use_admin_link,
)
from ..experimenter import decisions, plots
from ..experimenter.export import csv_text, export_stream
from ..participants import pilots
from ..participants.assignment import fresh_after
from ..participants.boot import trial_boot
from ..participants.outcomes import APPROVAL_COLUMNS, approval_rows, issued_codes
from ..studies.served import runtime
from ..trials import posted_scenes
from ..trials.posted_scenes import image_path
from ..trials.replays import replay_document

bp = Blueprint("admin", __name__, url_prefix="/admin")


#: Where a login may send the admin next: an admin path, nothing that could leave the site or split a header.
NEXT = re.compile(r"/admin/[A-Za-z0-9_./-]*")


@bp.route("/login", methods=["GET", "POST"])
def login():
    error = None
    status = 200
    if request.method == "POST":
        check_csrf()
        try:
            device = attempt_login(request.form.get("password", ""))
        except LoginBlocked:
            device, error, status = None, "Too many failed attempts. Try again in 15 minutes.", 429
        if device:
            target = request.args.get("next", "")
            return _signed_in(redirect(target if NEXT.fullmatch(target) and ".." not in target
                                       else url_for(".dashboard")), device)
        if status == 200:
            error, status = "Wrong password.", 401
    configured = bool(current_app.config.get("ADMIN_PASSWORD_HASH"))
    return render_template("admin/login.html", error=error, configured=configured), status


def _signed_in(response, device: str):
    """``response`` with the browser's device cookie (failed logins elsewhere then never lock it out)."""
    response.set_cookie(DEVICE_COOKIE, device, max_age=int(DEVICE_LIFETIME.total_seconds()), path="/admin",
                        httponly=True, secure=current_app.config.get("SESSION_COOKIE_SECURE", False),
                        samesite="Strict")
    return response


@bp.route("/link/<secret>", methods=["GET", "POST"])
def link(secret: str):
    """A one-time sign-in link (``scenesuggest study admin-link``): opening it shows a button, so a chat app's
    link preview does not spend it; the button signs in once, before the link expires, however many logins
    have failed meanwhile. A used, expired or unknown link is 410."""
    if request.method == "POST":
        check_csrf()
        device = use_admin_link(secret) if len(secret) <= 128 else None
        if device:
            return _signed_in(redirect(url_for(".dashboard")), device)
    elif len(secret) <= 128 and admin_link_live(secret):
        return render_template("admin/link.html", spent=False)
    return render_template("admin/link.html", spent=True), 410


@bp.post("/logout")
@admin_required
def logout():
    check_csrf()
    end_admin_session()
    return redirect(url_for(".login"))


@bp.get("/")
@admin_required
def dashboard():
    glances = [(rt.study, plots.glance(rt.study)) for rt in current_app.extensions["studies"].values()]
    studies = [(study, g["progress"], g) for study, g in glances]
    codes = {rt.study.id: issued_codes(rt.study.id) for rt in current_app.extensions["studies"].values()}
    starts = {study.id: url_for("participant.start", study_id=study.id, _external=True) for study, _ in glances}
    links = {study.id: {"participant": pilots.participant_link(study, starts[study.id]),
                        "pilot": pilots.test_link(current_app.config["SECRET_KEY"], study, starts[study.id])}
             for study, _ in glances}
    return render_template("admin/dashboard.html", studies=studies, codes=codes, outcomes=list(plots.OUTCOMES),
                           links=links)


@bp.get("/<study_id>/plots/<name>.svg")
@admin_required
def plot(study_id: str, name: str):
    """One of the dashboard's plots (:mod:`study_server.experimenter.plots`), drawn now. An SVG shown as an image runs
    no script; its own inline styles are all it may use."""
    study = runtime(study_id).study
    if name not in plots.DRAW:
        abort(404)
    return Response(plots.DRAW[name](study), mimetype="image/svg+xml",
                    headers={"Cache-Control": "no-store",
                             "Content-Security-Policy": "default-src 'none'; style-src 'unsafe-inline'"})


@bp.get("/<study_id>/participants")
@admin_required
def participants(study_id: str):
    study = runtime(study_id).study
    people = list(db.session.scalars(select(Participant).where(Participant.study_id == study_id)
                                     .order_by(Participant.id.desc())))
    return render_template("admin/participants.html", study=study, people=people,
                           stale_before=fresh_after(study, utcnow()))


@bp.get("/<study_id>/participants/<row:pid>")
@admin_required
def participant(study_id: str, pid: int):
    study = runtime(study_id).study
    p = db.session.get(Participant, pid)
    if p is None or p.study_id != study_id:
        abort(404)
    given = request.args.get("from", "0")
    if not (given.isascii() and given.isdigit() and int(given) <= MAX_SEQ):
        raise RequestError(400, f"expected an event seq from 0 to {MAX_SEQ}", "from")
    start = int(given)
    events = list(db.session.scalars(select(Event).where(Event.participant_id == pid, Event.seq >= start)
                                     .order_by(Event.seq).limit(PAGE_EVENTS + 1)))
    following = events[PAGE_EVENTS] if len(events) > PAGE_EVENTS else None
    events = events[:PAGE_EVENTS]
    logged = select(SessionLog).where(SessionLog.participant_id == pid)  # the server's log rows of this page's time
    if start and events:
        logged = logged.where(SessionLog.at >= events[0].server_t)
    if following is not None:
        logged = logged.where(SessionLog.at < following.server_t)
    timeline = [(r.at, "server", r.kind, shown(r.detail)) for r in db.session.scalars(logged.order_by(
        SessionLog.id).limit(PAGE_LOG))]
    timeline += [(e.server_t, f"event {e.seq}", e.type, shown(e.payload)) for e in events]
    timeline.sort(key=lambda x: (x[0] is None, x[0] or utcnow()))
    trials = list(db.session.scalars(select(Trial).where(Trial.participant_id == pid).order_by(Trial.position)))
    surveys = list(db.session.scalars(select(SurveyResponse).where(SurveyResponse.participant_id == pid)))
    pages = {"from": start, "next": following.seq if following is not None else None,
             "previous": max(0, start - PAGE_EVENTS) if start else None}
    return render_template("admin/participant.html", study=study, p=p, timeline=timeline, trials=trials,
                           surveys=surveys, pages=pages, shown_chars=DETAIL_CHARS)


#: A participant's page shows PAGE_EVENTS events at a time (and at most PAGE_LOG of the server's log rows between
#: them), each payload cut after DETAIL_CHARS characters: whatever a participant stored within the quota, the page
#: stays under about 2 MB, escaped (the export holds everything whole).
PAGE_EVENTS = 250
PAGE_LOG = 250
DETAIL_CHARS = 600


def shown(value) -> str:
    """A stored JSON value as a participant's page shows it: at most DETAIL_CHARS characters, then how many more."""
    text = json.dumps(value, sort_keys=True)
    if len(text) <= DETAIL_CHARS:
        return text
    return f"{text[:DETAIL_CHARS]} … ({len(text) - DETAIL_CHARS:,} characters more: the export holds them)"


def _trial_of(study_id: str, pid: int, index: int) -> Trial:
    p = db.session.get(Participant, pid)
    t = db.session.scalar(select(Trial).where(Trial.participant_id == pid, Trial.index == index)) \
        if p is not None and p.study_id == study_id else None
    if t is None:
        abort(404)
    return t


@bp.get("/<study_id>/participants/<row:pid>/trials/<row(signed=True):index>/replay")
@admin_required
def replay(study_id: str, pid: int, index: int):
    """A trial rebuilt from its events, step by step: the participants' editor, read-only."""
    rt = runtime(study_id)
    t = _trial_of(study_id, pid, index)
    boot = {"data": url_for(".replay_data", study_id=study_id, pid=pid, index=index),
            "back": url_for(".participant", study_id=study_id, pid=pid)}
    return render_template("admin/replay.html", study=rt.study, t=t, boot=boot,
                           scene_title=rt.study.scenes[t.scene_id].title)


@bp.get("/<study_id>/participants/<row:pid>/trials/<row(signed=True):index>/replay.json")
@admin_required
def replay_data(study_id: str, pid: int, index: int):
    rt = runtime(study_id)
    return jsonify(replay_document(rt, _trial_of(study_id, pid, index)))


@bp.post("/<study_id>/participants/<row:pid>/exclude")
@admin_required
def exclude(study_id: str, pid: int):
    check_csrf()
    runtime(study_id)
    p = db.session.get(Participant, pid)
    if p is None or p.study_id != study_id:
        abort(404)
    decisions.exclude(p, request.form.get("reason", ""))
    db.session.commit()
    return redirect(url_for(".participant", study_id=study_id, pid=pid))


@bp.post("/<study_id>/participants/<row:pid>/flags/<row:number>/clear")
@admin_required
def clear_flag(study_id: str, pid: int, number: int):
    """The experimenter has looked at a flag and clears it: it stays on record (cleared, when), and no longer
    makes the approval decision "review"."""
    check_csrf()
    runtime(study_id)
    p = db.session.get(Participant, pid)
    if p is None or p.study_id != study_id or number >= len(p.flags or []):
        abort(404)
    if decisions.clear_flag(p, number):
        db.session.commit()
    return redirect(url_for(".participant", study_id=study_id, pid=pid))


@bp.get("/<study_id>/preview")
@admin_required
def preview_grid(study_id: str):
    study = runtime(study_id).study
    images = {sid: image_path(s.target).is_file() for sid, s in study.scenes.items()}
    return render_template("admin/preview.html", study=study, images=images)


@bp.get("/<study_id>/preview/<condition>/<scene_id>")
@admin_required
def preview(study_id: str, condition: str, scene_id: str):
    rt = runtime(study_id)
    study = rt.study
    if condition not in [c.id for c in study.conditions] or scene_id not in study.scenes:
        abort(404)
    boot = _preview_boot(study, condition, scene_id, url_for(".preview_grid", study_id=study_id))
    return render_template("trial.html", study=study, p=None, trial=None, condition=study.condition(condition),
                           boot=boot, scene_title=study.scenes[scene_id].title, preview=True)


def _preview_boot(study, condition: str, scene_id: str, back: str) -> dict:
    return trial_boot(study, preview_token(study.id, condition, scene_id),
                      {"index": 0, "kind": "preview", "condition": condition, "scene": scene_id, "block": 0,
                       "number": 1, "of": 1}, back, preview=True)


def _authoring_condition(study) -> str:
    """Authoring composes with suggestions (oriented if the study has them) and search."""
    ids = [c.id for c in study.conditions]
    return next((c for c in ("full", "basic") if c in ids), ids[0])


@bp.get("/<study_id>/author/<scene_id>")
@admin_required
def author(study_id: str, scene_id: str):
    """The scene editor in authoring mode: opens the scene's target, saves it back, renders its image."""
    rt = runtime(study_id)
    study = rt.study
    if scene_id not in study.scenes:
        abort(404)
    condition = _authoring_condition(study)
    boot = _preview_boot(study, condition, scene_id, url_for(".preview_grid", study_id=study_id))
    target = study.scenes[scene_id].target
    boot["author"] = {"save": url_for(".author_save", study_id=study_id, scene_id=scene_id),
                      "image": url_for(".author_image", study_id=study_id, scene_id=scene_id),
                      "csrf": csrf_token(), "file": target.name, "frozen": posted_scenes.started(study_id)}
    return render_template("trial.html", study=study, p=None, trial=None, condition=study.condition(condition),
                           boot=boot, scene_title=study.scenes[scene_id].title, preview=True, author=True)


def _authoring_request(study_id: str, scene_id: str, key: str):
    if not csrf_ok(request.headers.get("X-CSRF-Token")):
        raise RequestError(400, "the page has expired; reload it and save again", "X-CSRF-Token")
    rt = runtime(study_id)
    if scene_id not in rt.study.scenes:
        raise RequestError(404, f"no scene {scene_id!r} in study {study_id!r}", "scene_id")
    posted_scenes.may_author(rt)
    doc = request.get_json(silent=True)
    if not isinstance(doc, dict) or key not in doc:
        raise RequestError(400, f"expected a JSON object with {key!r}", key)
    return rt, doc[key]


@bp.post("/<study_id>/author/<scene_id>")
@admin_required
def author_save(study_id: str, scene_id: str):
    rt, doc = _authoring_request(study_id, scene_id, "scene")
    target, objects = posted_scenes.save_target(rt, scene_id, doc)
    current_app.logger.info("target scene %s of %s saved by the admin", scene_id, study_id)
    return jsonify({"saved": str(target), "objects": objects})


@bp.route("/<study_id>/author/<scene_id>/image", methods=["GET", "POST"])
@admin_required
def author_image(study_id: str, scene_id: str):
    """GET: the target's rendered image; POST {"png": data URL}: save it beside the target."""
    if request.method == "GET":
        scenes = runtime(study_id).study.scenes
        path = image_path(scenes[scene_id].target) if scene_id in scenes else None
        if path is None or not path.is_file():
            abort(404)
        return send_file(path, mimetype="image/png", max_age=0)
    rt, data_url = _authoring_request(study_id, scene_id, "png")
    path, width, height = posted_scenes.save_image(rt, scene_id, data_url)
    return jsonify({"saved": str(path), "width": width, "height": height})


@bp.get("/<study_id>/export.zip")
@admin_required
def export(study_id: str):
    rt = runtime(study_id)
    stamp = utcnow().strftime("%Y%m%dT%H%M%SZ")
    # streamed as it is written: a batch of rows in memory at a time, whatever the study's size
    return Response(stream_with_context(export_stream(rt)), mimetype="application/zip",
                    headers={"Content-Disposition": f"attachment; filename={study_id}-{stamp}.zip"})


@bp.get("/<study_id>/approvals.csv")
@admin_required
def approvals(study_id: str):
    """Every participant with their platform id, session, status, code and the decision to take on the platform
    (:mod:`study_server.participants.outcomes`)."""
    runtime(study_id)
    stamp = utcnow().strftime("%Y%m%dT%H%M%SZ")
    return Response(csv_text(approval_rows(study_id), list(APPROVAL_COLUMNS)), mimetype="text/csv",
                    headers={"Content-Disposition": f"attachment; filename={study_id}-approvals-{stamp}.csv"})
