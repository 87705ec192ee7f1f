"""The JSON API under /api/: session state, events, suggestions, search, models, scenes, heartbeat, trial done.

Participants authenticate with ``Authorization: Bearer <session token>``; an admin's preview uses a signed
preview token and writes nothing. Errors are ``{"error": message, "field": name}`` with a 4xx status.
"""

from __future__ import annotations

import re

from flask import Blueprint, current_app, g, jsonify, request, url_for
from sqlalchemy import bindparam, select

from scenesuggest.contract.event_schema import json_schema
from scenesuggest.contract.events import MAX_SEQ, EventError, text_problem

from ..base import i18n
from ..base.errors import RequestError
from ..base.extensions import db, json_value
from ..base.models import Participant, Trial, utcnow
from ..base.openapi import openapi_document
from ..base.security import Preview, read_preview_token
from ..participants import flow
from ..studies.served import runtime
from ..trials import ingest, lists, replays, trial_check

bp = Blueprint("api", __name__, url_prefix="/api")


_BY_TOKEN = select(Participant).where(Participant.token == bindparam("token"))


def caller() -> Participant | Preview:
    header = request.headers.get("Authorization", "")
    if not header.startswith("Bearer ") or not header[7:].strip():
        raise RequestError(401, "missing session token (Authorization: Bearer …)", "Authorization")
    token = header[7:].strip()
    if token.startswith("preview."):
        preview = read_preview_token(token)
        if preview is None:
            raise RequestError(401, "invalid preview token", "Authorization")
        _speak(preview.study_id, None)
        return preview
    p = db.session.scalar(_BY_TOKEN, {"token": token}) if len(token) <= 64 else None
    if p is None:
        raise RequestError(401, "unknown session token", "Authorization")
    _speak(p.study_id, p.language)
    return p


def _speak(study_id: str, language: str | None) -> None:
    """What the answer's names are in (the model and suggestion tiles'): the participant's language, if the study
    still speaks it, else the study's default."""
    studies = current_app.extensions["studies"]
    if study_id in studies:
        spoken = studies[study_id].study.languages
        g.language = language if language in spoken else spoken[0]


#: What may decode to text no database can store: a JSON escape of a surrogate (paired ones are fine) or of NUL,
#: or a surrogate encoded as raw bytes (Python's json decoder lets those through).
SUSPECT_ESCAPE = re.compile(rb"\\u(?:[dD][89a-fA-F]|0000)|\xed[\xa0-\xbf]")


def _check_strings(value, path: str) -> None:
    """Every string (and key) of a body must be storable text; 422 names the first that is not."""
    if isinstance(value, str):
        problem = text_problem(value)
        if problem:
            raise RequestError(422, problem, path)
    elif isinstance(value, dict):
        for k, v in value.items():
            _check_strings(k, path)
            _check_strings(v, f"{path}.{k}" if path != "body" else str(k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _check_strings(v, f"{path}[{i}]")


def body() -> dict:
    """The request's JSON object; 400 names what is wrong. Decoded as the database's JSON is (orjson, three times
    faster than json on an event batch; json for what orjson refuses — a number past a double's range, a lone
    surrogate, NaN — so that validation can name the field that holds it)."""
    if not request.is_json:
        raise RequestError(400, "expected a JSON object body (Content-Type: application/json)", "body")
    raw = request.get_data(cache=True)
    try:
        data = json_value(raw)
    except ValueError as e:
        raise RequestError(400, f"the body is not JSON: {e}", "body") from None
    except RecursionError:  # json raises this, not a ValueError, for arrays nested thousands deep
        raise RequestError(400, "the JSON is nested too deeply", "body") from None
    if not isinstance(data, dict):
        raise RequestError(400, "expected a JSON object body", "body")
    # rare: only then walk the document (a body without a backslash or 0xED byte cannot match: two memchr scans
    # instead of the pattern's scan, which cost as much as decoding the body)
    if (b"\\" in raw or b"\xed" in raw) and SUSPECT_ESCAPE.search(raw):
        try:
            _check_strings(data, "body")
        except RecursionError:
            raise RequestError(400, "the JSON is nested too deeply", "body") from None
    return data


def trial_json(t: Trial | None, preview: Preview | None = None) -> dict | None:
    if preview is not None:
        return {"index": 0, "kind": "preview", "condition": preview.condition, "scene": preview.scene}
    if t is None:
        return None
    return {**t.describe(), "started": t.started_at is not None}


def _open(who) -> None:
    """A session that has ended (completed, excluded, declined …) changes nothing any more."""
    if isinstance(who, Participant) and not flow.is_open(who):
        raise RequestError(410, f"this session has ended (status {who.status!r}); it takes nothing more", "status",
                           extra={"status": who.status})


def _current(who) -> tuple[str, str, int]:
    """(condition, scene, trial index) of the caller's current trial."""
    if isinstance(who, Preview):
        return who.condition, who.scene, 0
    _open(who)
    t = flow.current_trial(who)
    if t is None:
        raise RequestError(409, f"no trial in progress (the session is at step {who.step!r})", "trial")
    return t.condition, t.scene_id, t.index


def _check_trial(who, data: dict) -> tuple[str, str, int]:
    condition, scene, index = _current(who)
    if data.get("trial") != index:
        raise RequestError(409, f"trial {data.get('trial')!r} is not the current trial ({index})", "trial")
    return condition, scene, index


@bp.get("/openapi.json")
def openapi():
    return jsonify(openapi_document())


@bp.get("/events/schema.json")
def event_schema():
    return jsonify(json_schema())


@bp.get("/session")
def session_state():
    who = caller()
    if isinstance(who, Preview):
        rt = runtime(who.study_id)
        return jsonify({"study": who.study_id, "preview": True, "status": "preview", "step": "trial",
                        "trial": trial_json(None, who), "trials": 1, "acked_seq": -1,
                        "limits": {"trial_minutes": rt.study.trial_minutes}})
    rt = runtime(who.study_id)
    plan = flow.trials(who)
    return jsonify({"study": who.study_id, "preview": False, "status": who.status, "step": who.step,
                    "position": who.position, "trial": trial_json(flow.current_trial(who)),
                    "trials": len([t for t in plan if t.kind == "trial"]), "acked_seq": who.acked_seq,
                    "limits": {"trial_minutes": rt.study.trial_minutes, "session_minutes": rt.study.session_minutes}})


@bp.post("/heartbeat")
def heartbeat():
    who = caller()
    if isinstance(who, Participant):
        _open(who)  # an ended session (excluded, completed …) is seen no more: 410, last_seen_at kept
        who.last_seen_at = utcnow()
        db.session.commit()
        return jsonify({"ok": True, "acked_seq": who.acked_seq})
    return jsonify({"ok": True, "acked_seq": -1})


@bp.post("/events")
def events():
    who = caller()
    data = body()
    _open(who)
    try:
        answer = ingest.take(who, runtime(who.study_id).study, data, request.content_length)
    except EventError as e:
        db.session.rollback()
        raise RequestError(422, e.message, e.field) from None
    return jsonify(answer)


def _participant(who) -> Participant | None:
    """The participant calling, None for an admin's preview (which stores nothing)."""
    return who if isinstance(who, Participant) else None


@bp.post("/suggest")
def suggest():
    who = caller()
    data = body()
    condition, scene_id, index = _check_trial(who, data)
    answer = lists.suggest(runtime(who.study_id), _participant(who), condition, scene_id, index, data)
    db.session.commit()
    return jsonify(answer)


@bp.get("/search")
def search():
    who = caller()
    text = request.args.get("q", "")
    if len(text) > 200:
        raise RequestError(400, "at most 200 characters", "q")
    if text_problem(text):
        raise RequestError(400, text_problem(text), "q")
    _open(who)
    try:
        limit = int(request.args.get("limit", 60))
    except ValueError:
        raise RequestError(400, "expected an integer", "limit") from None
    if not 1 <= limit <= 200:
        raise RequestError(400, "must be between 1 and 200", "limit")
    answer = lists.search(runtime(who.study_id), _participant(who), text, limit)
    db.session.commit()
    return jsonify(answer)


@bp.get("/models")
def models():
    who = caller()
    rt = runtime(who.study_id)
    language = i18n.page_language()
    return jsonify({"models": [rt.describe(m, language) for m in rt.fixed_list]})


@bp.get("/scenes/<scene_id>")
def scene(scene_id: str):
    who = caller()
    rt = runtime(who.study_id)
    allowed = {who.scene} if isinstance(who, Preview) else {t.scene_id for t in flow.trials(who)}
    if scene_id not in allowed or scene_id not in rt.study.scenes:
        raise RequestError(404, "no such scene in this session", "scene_id")
    which = request.args.get("which", "target")
    if which not in ("target", "start", "progress"):
        raise RequestError(400, "must be 'target', 'start' or 'progress'", "which")
    if which == "progress":
        if isinstance(who, Preview):
            raise RequestError(400, "a preview keeps no progress", "which")
        return jsonify(replays.progress(rt, who, scene_id))
    return jsonify(rt.scene(scene_id, which))


@bp.post("/trial/done")
def trial_done():
    """Finish the current trial with its final scene; a retry for an already finished trial is a no-op."""
    who = caller()
    data = body()
    if isinstance(who, Preview):
        _check_trial(who, data)
        return jsonify({"step": "trial", "preview": True})
    index = data.get("trial")
    if isinstance(index, bool) or not isinstance(index, int) or not -1 <= index <= MAX_SEQ:
        raise RequestError(400, "expected the trial index", "trial")
    last_seq = data.get("last_seq")  # the last event the page logged (pages of vocabulary 1 do not say)
    if last_seq is not None and (isinstance(last_seq, bool) or not isinstance(last_seq, int)
                                 or not -1 <= last_seq <= MAX_SEQ):
        raise RequestError(400, f"expected the seq of the page's last event (-1 to {MAX_SEQ})", "last_seq")
    _open(who)
    trial_check.done(runtime(who.study_id), who, index, data.get("scene"), last_seq)
    db.session.commit()
    return jsonify({"step": who.step, "position": who.position, "trial": trial_json(flow.current_trial(who)),
                    "next": url_for("participant.current", study_id=who.study_id)})
