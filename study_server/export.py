"""Export a study as tidy CSV tables plus ``manifest.json`` and a data dictionary.

Cells are safe to open in a spreadsheet: a text cell that begins with ``=``, ``+``, ``-``, ``@``, a tab, a
carriage return or ``'`` is written with a leading ``'`` (OWASP's advice against formula injection; numbers are
written as they are). :func:`scenesuggest.cells.unescape_cell` undoes it, and the project's reader
(``analysis.load``) applies it, so the tables load back to the stored values. Text that is not valid Unicode (a
lone surrogate stored before the server refused it) is written with a backslash escape (``\\udfff``) rather
than failing the export.

Tables (one row per …): ``participants`` (participant), ``trials`` (trial), ``events`` (logged event),
``suggestions`` (item of a list the server showed: context suggestions and search results, with ranks),
``picks`` (model placed: insert/replace events with their rank, source and whether it was final, by the one
definition in :mod:`scenesuggest.picks`), ``survey`` (answer), ``session_log`` (server-side observation: arrival,
resume, device check, failures). ``scenes.json`` holds what rebuilding and scoring a trial needs: each scene's
start and target objects, the categories' taxonomy parents and the target models' symmetry periods.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import subprocess
import zipfile
from datetime import UTC, datetime
from itertools import groupby
from pathlib import Path

from sqlalchemy import select, text

import scenesuggest
from scenesuggest.cells import safe_cell
from scenesuggest.library import INDEX_FILE
from scenesuggest.picks import picks
from scenesuggest.scoring import FORMULA

from .extensions import db
from .models import Event, Participant, SessionLog, ShownList, SurveyResponse, Trial, open_flags
from .studies import StudyRuntime
from .study_file import Study
from .trial_check import target_closeness

DICTIONARY: dict[str, dict[str, str]] = {
    "participants": {
        "participant": "participant number (database id)", "study": "study id",
        "study_hash": "sha256 of the study file",
        "platform": "prolific | mturk | link", "platform_id": "the platform's worker id",
        "row": "schedule row (Williams row × period) assigned on arrival", "status":
        "in_progress | completed | no_consent | screened_out | returned | excluded | technical",
        "step": "last step reached", "consent_version": "consent text version agreed to",
        "excluded_reason": "why an experimenter excluded the participant", "created_at": "arrival (UTC)",
        "last_seen_at": "last request (UTC)", "finished_at": "completion or early end (UTC)",
        "acked_seq": "highest contiguous event seq stored",
        "flags": "why the experimenter should review this participant (reasons separated by ' | '; empty: none; "
                 "flags the experimenter cleared are not listed)",
        "viewport_width": "browser window width at the device check (px)",
        "viewport_height": "height (px)", "user_agent": "browser user agent"},
    "trials": {
        "participant": "participant number", "position": "order in the session (0 = first)",
        "trial": "trial index (−1 = practice)", "kind": "practice | trial", "condition": "none | basic | full",
        "scene": "target scene id", "period": "period of the schedule row", "block": "block within the session",
        "started_at": "trial page first shown (UTC)", "done_at": "done acknowledged (UTC)",
        "final_objects": "objects in the final scene",
        "review": "why the trial should be reviewed: its events do not show the study's minimum work, or its scene "
                  "came less close to the target than [limits] min_target_score (empty: neither)",
        "replay": "whether the trial's events rebuild the final scene it submitted: match, mismatch: what differs, "
                  "pending: (events the page logged before 'done' not stored yet; made at the next 'done' or at "
                  "completion, then with '(events after seq N never arrived)' if some never did), or "
                  "unavailable: why (events of vocabulary 1 carry no object states, or the check failed)",
        "score": f"how close the final scene came to the target, 0..1: {FORMULA}",
        "matched": "target objects matched by an object of the final scene",
        "missing": "target objects nothing matched", "extra": "objects of the final scene that match nothing",
        "position_error_m": "mean distance of the matched objects from their targets (metres)",
        "orientation_error_deg": "mean angle of the matched objects from their targets' orientations, folded by "
                                 "each model's rotational symmetry (degrees)"},
    "events": {
        "participant": "participant number", "seq": "per-participant event number from 0", "page_id":
        "page load that sent it", "type": "event type (see the event vocabulary in manifest.json)",
        "trial": "trial index or empty", "client_t_ms": "client clock, ms since the epoch",
        "server_t": "server receive time (UTC)", "payload": "event payload as JSON",
        "vocabulary": "version of the event vocabulary the page spoke (2: scene changes carry the resulting object "
                      "states; see event_schema.json, and event_schema_v1.json when the data holds version 1)"},
    "suggestions": {
        "participant": "participant number", "list_id": "id of the list", "trial": "trial index",
        "source": "context | search", "rank": "1-based rank in the list", "category": "category",
        "model": "model id (search lists) or first model of the category (context lists)",
        "score": "engine score (context lists)", "created_at": "when the server made the list (UTC)",
        "query": "the query as JSON"},
    "picks": {
        "participant": "participant number", "seq": "event seq", "trial": "trial index",
        "client_t_ms": "client clock (ms)", "action": "insert | replace", "object": "editor object id",
        "model": "model id", "category": "category", "rank": "rank in the list it was picked from (empty if none)",
        "reciprocal_rank": "1 / rank (empty if none)", "source": "context | search | fixed",
        "list_id": "list it was picked from, when known",
        "final": "true unless a later pick of the trial replaced this one in place (the top suggestion is placed "
                 "at once; the participant's choice is the last pick of such a chain; MRR counts final picks)"},
    "survey": {"participant": "participant number", "survey": "demographics | exit", "question": "question id",
               "answer": "the answer (Likert 1..scale, choice text, number or free text)"},
    "session_log": {"participant": "participant number (empty for failures before arrival)", "kind":
                    "arrive | view | resume | device_check | consent | instructions | trial_start | trial_done | "
                    "finish | error | …", "at": "server time (UTC)", "detail": "details as JSON"},
}


def _iso(t) -> str:
    return t.isoformat() if t else ""


def _closeness(rt: StudyRuntime, t: Trial) -> dict:
    """How close the trial's final scene came to its target (empty cells without a final scene)."""
    if not t.final_scene:
        return dict.fromkeys(("score", "matched", "missing", "extra", "position_error_m", "orientation_error_deg"),
                             "")
    c = target_closeness(rt, t.scene_id, t.final_scene["objects"]).to_dict()
    c.pop("matches")
    return {k: ("" if isinstance(v, float) and v != v else v) for k, v in c.items()}


def scenes_document(rt: StudyRuntime) -> dict:
    """``scenes.json``: each scene's start and target objects, the taxonomy parent of every category the study's
    library and targets name, and the symmetry period of every target model (degrees; 360: none)."""
    scenes = {sid: {"title": s.title, "start": rt.scene(sid, "start")["objects"],
                    "target": rt.scene(sid, "target")["objects"]} for sid, s in rt.study.scenes.items()}
    library = rt.library.values() if (rt.study.library / INDEX_FILE).is_file() else []
    categories = {m.category for m in library} | {o["category"] for s in scenes.values() for o in s["target"]}
    models = sorted({o["model_id"] for s in scenes.values() for o in s["target"] if o["parent"] is not None})
    return {"scenes": scenes, "taxonomy": {c: rt.taxonomy.parent(c) for c in sorted(categories)},
            "symmetry_deg": {m: rt.period_of(m) for m in models}, "scoring": FORMULA}


def _rows(rt: StudyRuntime) -> dict[str, list[dict]]:
    study = rt.study
    s = db.session
    people = list(s.scalars(select(Participant).where(Participant.study_id == study.id).order_by(Participant.id)))
    ids = [p.id for p in people]
    out: dict[str, list[dict]] = {name: [] for name in DICTIONARY}
    for p in people:
        v = p.viewport or {}
        out["participants"].append({
            "participant": p.id, "study": p.study_id, "study_hash": p.study_hash, "platform": p.platform,
            "platform_id": p.platform_id, "row": p.row, "status": p.status, "step": p.step,
            "consent_version": p.consent_version or "", "excluded_reason": p.excluded_reason or "",
            "created_at": _iso(p.created_at), "last_seen_at": _iso(p.last_seen_at), "finished_at": _iso(p.finished_at),
            "acked_seq": p.acked_seq, "flags": " | ".join(f["reason"] for f in open_flags(p)),
            "viewport_width": v.get("width", ""), "viewport_height": v.get("height", ""),
            "user_agent": p.user_agent})
    if not ids:
        return out
    for t in s.scalars(select(Trial).where(Trial.participant_id.in_(ids)).order_by(Trial.participant_id,
                                                                                   Trial.position)):
        out["trials"].append({
            "participant": t.participant_id, "position": t.position, "trial": t.index, "kind": t.kind,
            "condition": t.condition, "scene": t.scene_id, "period": t.period, "block": t.block,
            "started_at": _iso(t.started_at), "done_at": _iso(t.done_at),
            "final_objects": len(t.final_scene["objects"]) if t.final_scene else "", "review": t.review or "",
            "replay": t.replay or "", **_closeness(rt, t)})
    events = list(s.scalars(select(Event).where(Event.participant_id.in_(ids)).order_by(Event.participant_id,
                                                                                          Event.seq)))
    for e in events:
        out["events"].append({"participant": e.participant_id, "seq": e.seq, "page_id": e.page_id, "type": e.type,
                              "trial": "" if e.trial is None else e.trial, "client_t_ms": repr(e.client_t),
                              "server_t": _iso(e.server_t), "payload": json.dumps(e.payload, sort_keys=True),
                              "vocabulary": e.vocabulary})
    for participant, own in groupby(events, key=lambda e: e.participant_id):
        for pick in picks([{"seq": e.seq, "t": e.client_t, "type": e.type, "trial": e.trial, "payload": e.payload}
                           for e in own]):
            out["picks"].append({
                "participant": participant, "seq": pick.seq, "trial": "" if pick.trial is None else pick.trial,
                "client_t_ms": repr(pick.t), "action": pick.action, "object": pick.object, "model": pick.model,
                "category": pick.category, "rank": "" if pick.rank is None else pick.rank,
                "reciprocal_rank": "" if pick.reciprocal_rank is None else pick.reciprocal_rank,
                "source": pick.source, "list_id": pick.list_id or "", "final": "true" if pick.final else "false"})
    for li in s.scalars(select(ShownList).where(ShownList.participant_id.in_(ids)).order_by(ShownList.created_at,
                                                                                           ShownList.id)):
        for item in li.items:
            out["suggestions"].append({
                "participant": li.participant_id, "list_id": li.id, "trial": "" if li.trial is None else li.trial,
                "source": li.source, "rank": item.get("rank"), "category": item.get("category", ""),
                "model": item.get("model") or (item.get("models") or [""])[0], "score": item.get("score", ""),
                "created_at": _iso(li.created_at), "query": json.dumps(li.query, sort_keys=True)})
    for r in s.scalars(select(SurveyResponse).where(SurveyResponse.participant_id.in_(ids))
                       .order_by(SurveyResponse.participant_id, SurveyResponse.survey)):
        for q, a in r.answers.items():
            out["survey"].append({"participant": r.participant_id, "survey": r.survey, "question": q,
                                  "answer": "" if a is None else a})
    for row in s.scalars(select(SessionLog).where(SessionLog.participant_id.in_(ids)).order_by(SessionLog.id)):
        out["session_log"].append({"participant": row.participant_id, "kind": row.kind, "at": _iso(row.at),
                                   "detail": json.dumps(row.detail, sort_keys=True)})
    return out


def csv_text(rows: list[dict], columns: list[str]) -> str:
    """CSV text of ``rows`` with spreadsheet-safe cells (see the data dictionary's "Text cells")."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    w.writeheader()
    w.writerows({k: safe_cell(v) for k, v in row.items()} for row in rows)
    return buf.getvalue()


def _code_version() -> str:
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, timeout=5,
                                cwd=Path(__file__).parent).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    return f"{scenesuggest.__version__}" + (f"+{commit}" if commit else "")


def _resources(study: Study) -> dict:
    """Which priors and model library the study ran with (the study file's hash does not say it when the study
    uses the server's own): the corpus and the SHA-256 of the priors file and of the library's index."""
    def sha256(path: Path) -> str | None:
        return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None

    return {"corpus": study.corpus, "server_resources": study.server_resources,
            "priors_sha256": sha256(study.priors), "library_index_sha256": sha256(study.library / INDEX_FILE)}


def _engines(rt: StudyRuntime) -> dict:
    """Per condition that suggests: its engine's name, version, options and the SHA-256 of the file it answers
    from (an HTTP engine: its fallback's file; the URL is left out, as it may carry a secret)."""
    out = {}
    for condition, e in rt.engine_files().items():
        file = e.pop("file")
        if e["engine"] == "http":
            e["options"] = {k: v for k, v in e["options"].items() if k != "url"}
        out[condition] = {**e, "file_sha256": hashlib.sha256(file.read_bytes()).hexdigest()
                          if file is not None and file.is_file() else None}
    return out


def export_files(rt: StudyRuntime) -> dict[str, str]:
    """File name → content of a complete export of the study ``rt`` runs."""
    from scenesuggest.event_schema import json_schema
    from scenesuggest.events import VERSION

    study = rt.study
    rows = _rows(rt)
    files = {f"{name}.csv": csv_text(rows[name], list(columns)) for name, columns in DICTIONARY.items()}
    try:
        schema_version = db.session.execute(text("SELECT version_num FROM alembic_version")).scalar()
    except Exception:
        db.session.rollback()
        schema_version = None
    dictionary = ["# Data dictionary", ""]
    for name, columns in DICTIONARY.items():
        dictionary += [f"## {name}.csv", "", "| column | meaning |", "|---|---|"]
        dictionary += [f"| {c} | {m} |" for c, m in columns.items()] + [""]
    dictionary += ["## Text cells", "",
                   "A text cell beginning with `=`, `+`, `-`, `@`, a tab, a carriage return or `'` is written "
                   "with one leading `'` so that spreadsheets show it as text instead of running it as a formula "
                   "(OWASP's advice on CSV injection); numbers are written as they are. Remove that one "
                   "`'` to get the stored value (`analysis.load.read_export` does). Text that was stored without "
                   "being valid Unicode appears with backslash escapes (`\\udfff`).", ""]
    files["data_dictionary.md"] = "\n".join(dictionary)
    files["event_schema.json"] = json.dumps(json_schema(), indent=1)
    for version in sorted({int(e["vocabulary"]) for e in rows["events"]} - {VERSION}):  # older pages' events
        files[f"event_schema_v{version}.json"] = json.dumps(json_schema(version), indent=1)
    files["scenes.json"] = json.dumps(scenes_document(rt), indent=1, sort_keys=True)
    manifest = {
        "study": study.id, "title": study.title, "study_hash": study.hash, "study_file": study.path.name,
        "code_version": _code_version(), "schema_version": schema_version,
        "exported_at": datetime.now(UTC).isoformat(), "row_counts": {n: len(r) for n, r in rows.items()},
        "files": {n: hashlib.sha256(c.encode()).hexdigest() for n, c in sorted(files.items())},
        "design": {"kind": study.design, "blocking": study.blocking, "rows": study.n_rows,
                   "conditions": [c.id for c in study.conditions], "periods": [list(p) for p in study.periods]},
        "resources": _resources(study),
        "engines": _engines(rt),
    }
    files["manifest.json"] = json.dumps(manifest, indent=1)
    return files


def export_to(rt: StudyRuntime, out: Path) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    files = export_files(rt)
    for name, content in files.items():
        (out / name).write_text(content, encoding="utf-8")
    return json.loads(files["manifest.json"])


def export_zip(rt: StudyRuntime) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, content in export_files(rt).items():
            z.writestr(f"{rt.study.id}/{name}", content)
    return buf.getvalue()
