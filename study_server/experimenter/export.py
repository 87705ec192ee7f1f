"""Export a study as tidy CSV tables plus ``manifest.json`` and a data dictionary.

Cells are safe to open in a spreadsheet: a text cell is written as it is only when it is a number or begins with a
letter, a digit or an inert mark such as JSON's ``{`` (:data:`scenesuggest.contract.cells.INERT`); any other
(``=``, ``+``, ``-``, ``@``, a tab, a space, a no-break space, a byte-order mark, a full-width ``＝``, ``|``, ``'`` …)
gets a leading ``'``, so that no spreadsheet runs a participant's text as a formula.
:func:`scenesuggest.contract.cells.unescape_cell` undoes it, and the project's reader (``analysis.load``) applies
it, so the tables load back to the stored values. Text that is not valid Unicode (a lone surrogate stored before
the server refused it) is written with a backslash escape (``\\udfff``) rather than failing the export.

Tables (one row per …): ``participants`` (participant), ``trials`` (trial), ``events`` (logged event),
``suggestions`` (item of a list the server showed: context suggestions and search results, with ranks),
``picks`` (model placed: insert/replace events with their rank, source and whether it was final, by the one
definition in :mod:`scenesuggest.contract.picks`), ``survey`` (answer), ``session_log`` (server-side observation:
arrival, resume, device check, failures). ``scenes.json`` holds what rebuilding and scoring a trial needs: each scene's
start and target objects, the categories' taxonomy parents and the target models' symmetry periods.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import subprocess
import tempfile
import zipfile
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

from sqlalchemy import select, text

import scenesuggest
from scenesuggest.contract.cells import safe_cell
from scenesuggest.contract.events import as_event
from scenesuggest.contract.picks import PICK_INPUTS, PICK_PAYLOADS, picks
from scenesuggest.contract.scoring import FORMULA
from scenesuggest.library.index import INDEX_FILE

from ..base.extensions import db
from ..base.models import Event, Participant, SessionLog, ShownList, SurveyResponse, Trial, open_flags
from ..participants import flow
from ..studies.served import StudyRuntime
from ..studies.study_file import Study
from ..trials.trial_check import target_closeness
from .export_schema import DICTIONARY, data_package, dictionary_markdown


def _seconds(value: float | None) -> str | float:
    return "" if value is None else round(value, 3)


def _iso(t) -> str:
    """A stored time (naive, UTC) as ISO 8601 with microseconds always written (one format for every cell)."""
    return t.isoformat(timespec="microseconds") if t else ""


CLOSENESS = ("score", "matched", "missing", "extra", "position_error_m", "orientation_error_deg")


def _closeness(rt: StudyRuntime, t: Trial) -> dict:
    """How close the trial's final scene came to its target, as the server found it at "done" (computed now only
    for a trial done before the result was stored); empty cells without a final scene or when the check failed."""
    found = t.closeness
    if found is None and t.final_scene:
        found = target_closeness(rt, t.scene_id, t.final_scene["objects"]).record()
    return {k: "" if (found or {}).get(k) is None else found[k] for k in CLOSENESS}


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


#: Rows read from the database at a time, and written between two chunks of a streamed export: what the export
#: holds in memory at once, whatever the study's size.
BATCH = 1000


def _stream(statement):
    """The rows of ``statement`` read ``BATCH`` at a time (a server-side cursor where the database has one)."""
    return db.session.scalars(statement.execution_options(yield_per=BATCH))


def _pick_rows(participant: int, events: list[dict]) -> Iterator[dict]:
    for pick in picks(events):
        yield {"participant": participant, "seq": pick.seq, "trial": "" if pick.trial is None else pick.trial,
               "client_t_ms": repr(pick.t), "action": pick.action, "object": pick.object, "model": pick.model,
               "category": pick.category, "rank": "" if pick.rank is None else pick.rank,
               "reciprocal_rank": "" if pick.reciprocal_rank is None else pick.reciprocal_rank,
               "source": pick.source, "list_id": pick.list_id or "", "final": "true" if pick.final else "false"}


def _participants(rt: StudyRuntime, ids, seen: dict) -> Iterator[dict]:
    languages = seen.setdefault("languages", set())
    for p in _stream(select(Participant).where(Participant.study_id == rt.study.id).order_by(Participant.id)):
        v = p.viewport or {}
        if p.language:
            languages.add(p.language)
        yield {"participant": p.id, "study": p.study_id, "study_hash": p.study_hash, "platform": p.platform,
               "platform_id": p.platform_id, "row": p.row, "status": p.status, "step": p.step,
               "consent_version": p.consent_version or "", "excluded_reason": p.excluded_reason or "",
               "created_at": _iso(p.created_at), "last_seen_at": _iso(p.last_seen_at),
               "finished_at": _iso(p.finished_at), "acked_seq": p.acked_seq,
               "flags": " | ".join(f["reason"] for f in open_flags(p)), "viewport_width": v.get("width", ""),
               "viewport_height": v.get("height", ""),
               "device_fps": "" if v.get("fps") is None else v["fps"], "device_renderer": v.get("renderer", ""),
               "screened_out_reasons": " | ".join(v.get("reasons", ())), "user_agent": p.user_agent,
               "language": p.language or "",
               "pilot": "true" if p.pilot else "false"}


def _trials(rt: StudyRuntime, ids, seen: dict) -> Iterator[dict]:
    """The trials; ``seen["conditions"]`` and ``seen["scenes"]`` collect the ids they hold."""
    conditions, scenes = seen.setdefault("conditions", set()), seen.setdefault("scenes", set())
    for t in _stream(select(Trial).where(Trial.participant_id.in_(ids)).order_by(Trial.participant_id,
                                                                               Trial.position)):
        conditions.add(t.condition)
        scenes.add(t.scene_id)
        yield {"participant": t.participant_id, "position": t.position, "trial": t.index, "kind": t.kind,
               "condition": t.condition, "scene": t.scene_id, "period": t.period, "block": t.block,
               "started_at": _iso(t.started_at), "done_at": _iso(t.done_at),
               "briefing_seconds": _seconds(flow.briefing_seconds(t)),
               "final_objects": len(t.final_scene["objects"]) if t.final_scene else "",
               "review": t.review or "", "replay": t.replay or "", **_closeness(rt, t)}


def _events(rt: StudyRuntime, ids, seen: dict) -> Iterator[dict]:
    """The events; ``seen["vocabularies"]`` collects the vocabularies met, and ``seen["picks"]`` takes each
    participant's events that picks are made of (one pass over the largest table)."""
    rows = db.session.execute(select(Event.participant_id, Event.seq, Event.page_id, Event.type, Event.trial,
                                     Event.client_t, Event.server_t, Event.payload, Event.vocabulary)
                              .where(Event.participant_id.in_(ids)).order_by(Event.participant_id, Event.seq)
                              .execution_options(yield_per=BATCH))
    vocabularies, own, current = seen.setdefault("vocabularies", set()), [], None
    for e in rows:
        if e.participant_id != current:
            seen["picks"](current, own)
            own, current = [], e.participant_id
        vocabularies.add(int(e.vocabulary))
        if e.type in PICK_INPUTS:  # what picks need of it (a move's or a turn's object states are not)
            own.append(as_event(e.seq, e.client_t, e.type, e.trial, e.payload if e.type in PICK_PAYLOADS else {}))
        yield {"participant": e.participant_id, "seq": e.seq, "page_id": e.page_id, "type": e.type,
               "trial": "" if e.trial is None else e.trial, "client_t_ms": repr(e.client_t),
               "server_t": _iso(e.server_t), "payload": json.dumps(e.payload, sort_keys=True),
               "vocabulary": e.vocabulary}
    seen["picks"](current, own)


def _suggestions(rt: StudyRuntime, ids, seen: dict) -> Iterator[dict]:
    for li in _stream(select(ShownList).where(ShownList.participant_id.in_(ids)).order_by(ShownList.created_at,
                                                                                         ShownList.id)):
        for item in li.items:
            yield {"participant": li.participant_id, "list_id": li.id,
                   "trial": "" if li.trial is None else li.trial, "source": li.source, "rank": item.get("rank"),
                   "category": item.get("category", ""),
                   "model": item.get("model") or (item.get("models") or [""])[0],
                   "score": item.get("score", ""), "created_at": _iso(li.created_at),
                   "query": json.dumps(li.query, sort_keys=True)}


def _survey(rt: StudyRuntime, ids, seen: dict) -> Iterator[dict]:
    for r in _stream(select(SurveyResponse).where(SurveyResponse.participant_id.in_(ids))
                     .order_by(SurveyResponse.participant_id, SurveyResponse.survey)):
        for q, a in r.answers.items():
            yield {"participant": r.participant_id, "survey": r.survey, "question": q,
                   "answer": "" if a is None else a}


def _session_log(rt: StudyRuntime, ids, seen: dict) -> Iterator[dict]:
    for row in _stream(select(SessionLog).where(SessionLog.participant_id.in_(ids)).order_by(SessionLog.id)):
        yield {"participant": row.participant_id, "kind": row.kind, "at": _iso(row.at),
               "detail": json.dumps(row.detail, sort_keys=True)}


#: Each table's rows, read from the database as they are written (``picks`` is found in the events' pass).
_TABLES = {"participants": _participants, "trials": _trials, "events": _events, "suggestions": _suggestions,
           "survey": _survey, "session_log": _session_log}


def _table(rt: StudyRuntime, name: str, seen: dict) -> Iterator[dict]:
    """The rows of the table ``name`` of the study ``rt`` runs (none for ``picks``, found in the events' pass);
    ``seen`` collects what the events' pass finds (:func:`_events`)."""
    ids = select(Participant.id).where(Participant.study_id == rt.study.id).scalar_subquery()
    rows = _TABLES.get(name)
    return rows(rt, ids, seen) if rows else iter(())


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


class _Sink:
    """Where an export's files go, one at a time, as text; each file's SHA-256 and size are taken as it is
    written (for the manifest)."""

    def begin(self, name: str) -> None:
        self.name, self.digest, self.size = name, hashlib.sha256(), 0

    def write(self, text: str) -> None:
        data = text.encode("utf-8")
        self.digest.update(data)
        self.size += len(data)
        self._put(data)

    def end(self) -> str:
        self._close()
        return self.digest.hexdigest()


class FolderSink(_Sink):
    """Into files of the folder ``out``, readable by their owner only (0600; a new folder 0700), as backups are:
    an export holds what participants did and the ids their platforms know them by."""

    def __init__(self, out: Path):
        out.mkdir(mode=0o700, parents=True, exist_ok=True)
        self.out = out

    def begin(self, name: str) -> None:
        super().begin(name)
        fd = os.open(self.out / name, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o600)  # no link
        os.fchmod(fd, 0o600)  # a file of an earlier export may have been readable by others
        self.file = os.fdopen(fd, "wb")

    def _put(self, data: bytes) -> None:
        self.file.write(data)

    def _close(self) -> None:
        self.file.close()


class ZipSink(_Sink):
    """Into a zip archive on ``stream`` (which may be a pipe: the archive is then written front to back)."""

    def __init__(self, stream, folder: str):
        self.zip = zipfile.ZipFile(stream, "w", zipfile.ZIP_DEFLATED)
        self.folder = folder

    def begin(self, name: str) -> None:
        super().begin(name)
        self.member = self.zip.open(f"{self.folder}/{name}", "w", force_zip64=True)

    def _put(self, data: bytes) -> None:
        self.member.write(data)

    def _close(self) -> None:
        self.member.close()

    def finish(self) -> None:
        self.zip.close()


class _HeldPicks:
    """The picks, found while the events are read (one pass over the largest table), kept in a file that stays in
    memory while small and spills to disk after, and written at their turn."""

    def __init__(self):
        # closed once copied; an export abandoned half-way, a download cut off, leaves it to the collector
        self.file = tempfile.SpooledTemporaryFile(max_size=8 << 20, mode="w+", encoding="utf-8",  # noqa: SIM115
                                                  newline="")
        self.writer = csv.DictWriter(self.file, fieldnames=list(DICTIONARY["picks"]), lineterminator="\n")
        self.count = 0

    def take(self, participant: int | None, events: list[dict]) -> None:
        """Keep the picks of ``participant``'s events (None: nothing, before the first participant)."""
        for row in _pick_rows(participant, events) if participant is not None else ():
            self.writer.writerow({k: safe_cell(v) for k, v in row.items()})
            self.count += 1

    def copy(self, buf: io.StringIO, sink: _Sink) -> Iterator[None]:
        """Write the held rows into ``sink`` after what ``buf`` holds, a chunk at a time."""
        self.file.seek(0)
        while chunk := self.file.read(1 << 20):
            buf.write(chunk)
            _flush(buf, sink)
            yield None
        self.file.close()


def _flush(buf: io.StringIO, sink: _Sink) -> None:
    sink.write(buf.getvalue())
    buf.seek(0)
    buf.truncate()


def _write_table(rt: StudyRuntime, name: str, sink: _Sink, seen: dict, picks: _HeldPicks) -> Iterator[None]:
    """Write ``name``.csv into ``sink``, ``BATCH`` rows at a time (yielding after each); returns its row count."""
    sink.begin(f"{name}.csv")
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(DICTIONARY[name]), lineterminator="\n")
    writer.writeheader()
    count = 0
    if name == "picks":  # written, escaped, while the events were read
        yield from picks.copy(buf, sink)
        count = picks.count
    for row in _table(rt, name, seen):
        writer.writerow({k: safe_cell(v) for k, v in row.items()})
        count += 1
        if count % BATCH == 0:
            _flush(buf, sink)
            yield None
    sink.write(buf.getvalue())
    return count


def _schema_version() -> str | None:
    """The database's schema revision (None where it has no Alembic table)."""
    try:
        return db.session.execute(text("SELECT version_num FROM alembic_version")).scalar()
    except Exception:
        db.session.rollback()
        return None


def _manifest(rt: StudyRuntime, counts: dict, hashes: dict, exported_at: str) -> dict:
    study = rt.study
    return {
        "study": study.id, "title": study.title, "study_hash": study.hash, "study_file": study.path.name,
        "code_version": _code_version(), "schema_version": _schema_version(),
        "exported_at": exported_at, "row_counts": counts,
        "files": dict(sorted(hashes.items())),
        "design": {"kind": study.design, "blocking": study.blocking, "rows": study.n_rows,
                   "conditions": [c.id for c in study.conditions], "periods": [list(p) for p in study.periods]},
        "resources": _resources(study),
        "engines": _engines(rt),
    }


def write_export(rt: StudyRuntime, sink: _Sink) -> Iterator[dict | None]:
    """Write a complete export of the study ``rt`` runs into ``sink``, table by table, ``BATCH`` rows at a time;
    yields after each batch (so a caller can send what is written) and last the manifest."""
    from scenesuggest.contract.event_schema import json_schema
    from scenesuggest.contract.events import VERSION

    hashes, counts, picks = {}, {}, _HeldPicks()
    seen = {"picks": picks.take}

    def whole(name: str, text: str) -> None:
        sink.begin(name)
        sink.write(text)
        hashes[name] = sink.end()

    for name in DICTIONARY:
        counts[name] = yield from _write_table(rt, name, sink, seen, picks)
        hashes[f"{name}.csv"] = sink.end()
        yield None
    exported_at = datetime.now(UTC).isoformat()
    whole("data_dictionary.md", dictionary_markdown())
    package = data_package(rt.study, hashes, exported_at, seen)
    whole("datapackage.json", json.dumps(package, indent=1, ensure_ascii=False))
    whole("event_schema.json", json.dumps(json_schema(), indent=1))
    for version in sorted(seen.get("vocabularies", set()) - {VERSION}):  # older pages' events
        whole(f"event_schema_v{version}.json", json.dumps(json_schema(version), indent=1))
    whole("scenes.json", json.dumps(scenes_document(rt), indent=1, sort_keys=True))
    manifest = _manifest(rt, counts, hashes, exported_at)
    whole("manifest.json", json.dumps(manifest, indent=1))
    yield manifest


def export_to(rt: StudyRuntime, out: Path) -> dict:
    """Write the export into the folder ``out``; returns its manifest."""
    *_, manifest = write_export(rt, FolderSink(out))
    return manifest


class _Pipe:
    """A write-only stream whose bytes are taken away as they come (no ``tell``: zipfile then writes front to
    back, sizes after each member)."""

    def __init__(self):
        self.chunks: list[bytes] = []

    def write(self, data: bytes) -> int:
        self.chunks.append(bytes(data))
        return len(data)

    def flush(self) -> None:
        pass

    def take(self) -> bytes:
        data, self.chunks = b"".join(self.chunks), []
        return data


def export_stream(rt: StudyRuntime) -> Iterator[bytes]:
    """The export as a zip archive (one folder named for the study), in pieces as it is written: what is held in
    memory at once is a batch of rows, whatever the study's size."""
    pipe = _Pipe()
    sink = ZipSink(pipe, rt.study.id)
    for _ in write_export(rt, sink):
        if piece := pipe.take():
            yield piece
    sink.finish()
    yield pipe.take()


def export_zip(rt: StudyRuntime) -> bytes:
    """The whole export as one zip archive in memory (tests; the admin streams :func:`export_stream`)."""
    return b"".join(export_stream(rt))


def export_files(rt: StudyRuntime) -> dict[str, str]:
    """File name → content of a complete export (tests)."""
    with zipfile.ZipFile(io.BytesIO(export_zip(rt))) as z:
        return {n.split("/", 1)[1]: z.read(n).decode("utf-8") for n in z.namelist()}
