"""Admin pages under /admin/: login, live progress, participant timelines, exclusion, previews, export."""

from __future__ import annotations

import json
import secrets
from collections import Counter
from datetime import timedelta

from flask import Blueprint, Response, abort, current_app, redirect, render_template, request, session, url_for
from sqlalchemy import func, select

from ..export import export_zip
from ..extensions import db
from ..models import Event, Participant, SessionLog, SurveyResponse, Trial, log, utcnow
from ..runtime import runtime
from ..security import admin_required, attempt_login, check_csrf, client_ip, login_blocked
from .api import preview_token

bp = Blueprint("admin", __name__, url_prefix="/admin")


@bp.route("/login", methods=["GET", "POST"])
def login():
    error = None
    status = 200
    if request.method == "POST":
        check_csrf()
        if login_blocked(client_ip()):
            error, status = "Too many failed attempts. Try again in 15 minutes.", 429
        elif attempt_login(request.form.get("password", "")):
            target = request.args.get("next", "")
            return redirect(target if target.startswith("/admin/") else url_for(".dashboard"))
        else:
            error, status = "Wrong password.", 401
    configured = bool(current_app.config.get("ADMIN_PASSWORD_HASH"))
    return render_template("admin/login.html", error=error, configured=configured), status


@bp.post("/logout")
@admin_required
def logout():
    check_csrf()
    session.clear()
    return redirect(url_for(".login"))


def progress(study) -> dict:
    """Counts per schedule row and per condition of completed / in progress / stale / excluded / other."""
    fresh = utcnow() - timedelta(minutes=study.stale_after_minutes)
    people = db.session.execute(select(Participant.row, Participant.status, Participant.last_seen_at)
                                .where(Participant.study_id == study.id)).all()
    rows = [Counter() for _ in range(study.n_rows)]
    totals = Counter()
    for row, status, seen in people:
        state = "in_progress" if status == "in_progress" and seen >= fresh else (
            "stale" if status == "in_progress" else status)
        if 0 <= row < len(rows):
            rows[row][state] += 1
        totals[state] += 1
    trials = db.session.execute(
        select(Trial.condition, Trial.done_at.is_not(None), func.count()).join(Participant)
        .where(Participant.study_id == study.id, Trial.kind == "trial").group_by(Trial.condition,
                                                                                 Trial.done_at.is_not(None))).all()
    conditions = {c.id: Counter() for c in study.conditions}
    for condition, done, n in trials:
        conditions.setdefault(condition, Counter())["done" if done else "open"] += n
    return {"rows": rows, "totals": totals, "conditions": conditions}


@bp.get("/")
@admin_required
def dashboard():
    studies = [(rt.study, progress(rt.study)) for rt in current_app.extensions["studies"].values()]
    return render_template("admin/dashboard.html", studies=studies)


@bp.get("/<study_id>/participants")
@admin_required
def participants(study_id: str):
    study = runtime(study_id).study
    people = list(db.session.scalars(select(Participant).where(Participant.study_id == study_id)
                                     .order_by(Participant.id.desc())))
    return render_template("admin/participants.html", study=study, people=people,
                           stale_before=utcnow() - timedelta(minutes=study.stale_after_minutes))


@bp.get("/<study_id>/participants/<int:pid>")
@admin_required
def participant(study_id: str, pid: int):
    study = runtime(study_id).study
    p = db.session.get(Participant, pid)
    if p is None or p.study_id != study_id:
        abort(404)
    timeline = [(r.at, "server", r.kind, json.dumps(r.detail, sort_keys=True))
                for r in db.session.scalars(select(SessionLog).where(SessionLog.participant_id == pid))]
    timeline += [(e.server_t, f"event {e.seq}", e.type, json.dumps(e.payload, sort_keys=True))
                 for e in db.session.scalars(select(Event).where(Event.participant_id == pid).order_by(Event.seq)
                                             .limit(5000))]
    timeline.sort(key=lambda x: x[0])
    trials = list(db.session.scalars(select(Trial).where(Trial.participant_id == pid).order_by(Trial.position)))
    surveys = list(db.session.scalars(select(SurveyResponse).where(SurveyResponse.participant_id == pid)))
    return render_template("admin/participant.html", study=study, p=p, timeline=timeline, trials=trials,
                           surveys=surveys)


@bp.post("/<study_id>/participants/<int:pid>/exclude")
@admin_required
def exclude(study_id: str, pid: int):
    check_csrf()
    runtime(study_id)
    p = db.session.get(Participant, pid)
    if p is None or p.study_id != study_id:
        abort(404)
    reason = request.form.get("reason", "").strip()[:1000]
    if not reason:
        abort(400, "A reason is required to exclude a participant.")
    p.status = "excluded"
    p.excluded_reason = reason
    log("excluded", p, reason=reason)
    db.session.commit()
    return redirect(url_for(".participant", study_id=study_id, pid=pid))


@bp.get("/<study_id>/preview")
@admin_required
def preview_grid(study_id: str):
    study = runtime(study_id).study
    return render_template("admin/preview.html", study=study)


@bp.get("/<study_id>/preview/<condition>/<scene_id>")
@admin_required
def preview(study_id: str, condition: str, scene_id: str):
    rt = runtime(study_id)
    study = rt.study
    if condition not in [c.id for c in study.conditions] or scene_id not in study.scenes:
        abort(404)
    boot = {"study": study_id, "token": preview_token(study_id, condition, scene_id), "preview": True,
            "trial": {"index": 0, "kind": "preview", "condition": condition, "scene": scene_id, "block": 0,
                      "number": 1, "of": 1}, "page_id": secrets.token_hex(8),
            "api": url_for("api.session_state").rsplit("/", 1)[0],
            "next": url_for(".preview_grid", study_id=study_id), "limits": {"trial_minutes": study.trial_minutes}}
    return render_template("trial.html", study=study, p=None, trial=None, condition=study.condition(condition),
                           boot=boot, scene_title=study.scenes[scene_id].title, preview=True)


@bp.get("/<study_id>/export.zip")
@admin_required
def export(study_id: str):
    study = runtime(study_id).study
    data = export_zip(study)
    stamp = utcnow().strftime("%Y%m%dT%H%M%SZ")
    return Response(data, mimetype="application/zip",
                    headers={"Content-Disposition": f"attachment; filename={study_id}-{stamp}.zip"})
