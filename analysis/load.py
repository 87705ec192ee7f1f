"""Read a study's data: an export folder (``scenesuggest study export``) or the study database itself.

Either way the result is a :class:`StudyData` of tidy tables — participants, trials, events (payload decoded)
and survey answers — plus a manifest saying where they came from and, from an export, ``scenes.json`` (each
scene's start and target, the taxonomy and symmetry periods that rebuilding and scoring a trial need). The
database is read with plain SQL over the server's tables; the study server is never imported.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from scenesuggest.contract.cells import unescape_cell

from .errors import AnalysisError

#: Condition order when the data does not state one (the paper's: no suggestions, basic, full).
CANONICAL_CONDITIONS = ("none", "basic", "full")

REQUIRED = {
    "participants": ["participant", "status"],
    "trials": ["participant", "position", "trial", "kind", "condition", "scene"],
    "events": ["participant", "seq", "type", "trial", "client_t_ms", "payload"],
    "survey": ["participant", "survey", "question", "answer"],
}


@dataclass
class StudyData:
    participants: pd.DataFrame
    trials: pd.DataFrame
    events: pd.DataFrame
    survey: pd.DataFrame
    manifest: dict = field(default_factory=dict)
    #: ``scenes.json`` of an export ({} when the data has none: a database, or an export made before it existed)
    scenes: dict = field(default_factory=dict)

    @property
    def conditions(self) -> list[str]:
        """Conditions in the study's order (the first is the reference level of every model)."""
        stated = list(self.manifest.get("design", {}).get("conditions") or [])
        present = [c for c in self.trials["condition"].dropna().unique().tolist()]
        order = stated or [c for c in CANONICAL_CONDITIONS if c in present]
        return order + sorted(c for c in present if c not in order)


def _check_columns(name: str, frame: pd.DataFrame) -> pd.DataFrame:
    missing = [c for c in REQUIRED[name] if c not in frame.columns]
    if missing:
        raise AnalysisError(f"column {missing[0]!r} is missing (has: {', '.join(map(str, frame.columns))})",
                            f"{name}.csv")
    return frame


def _decode(payload) -> dict:
    if isinstance(payload, dict):
        return payload
    if payload is None or (isinstance(payload, float) and pd.isna(payload)) or payload == "":
        return {}
    try:
        value = json.loads(payload)
    except (TypeError, ValueError) as e:
        raise AnalysisError(f"an event payload is not JSON ({e})", "events.csv: column 'payload'") from None
    return value if isinstance(value, dict) else {}


def _answer_text(answer) -> str | None:
    """A survey answer as the export writes it: text (a number as Python prints it), None when not given."""
    if answer is None or (isinstance(answer, float) and answer != answer):
        return None
    return answer if isinstance(answer, str) else str(answer)


def _normalise(data: StudyData) -> StudyData:
    """One shape whichever source the data came from: payloads as dicts, times and trial numbers as numbers,
    participants as text, survey answers as text, ``pilot`` as a boolean."""
    data.survey["answer"] = pd.Series([_answer_text(a) for a in data.survey["answer"]], index=data.survey.index,
                                      dtype=object)
    ev = data.events
    ev["payload"] = [_decode(p) for p in ev["payload"]]
    ev["client_t_ms"] = pd.to_numeric(ev["client_t_ms"], errors="coerce")
    ev["trial"] = pd.to_numeric(ev["trial"], errors="coerce")
    data.trials["trial"] = pd.to_numeric(data.trials["trial"], errors="coerce")
    for frame in (data.participants, data.trials, data.events, data.survey):
        frame["participant"] = frame["participant"].astype(str)
    # pilots (test runs, simulated participants): none in data from before they were marked
    pilot = data.participants["pilot"] if "pilot" in data.participants else pd.Series(False, data.participants.index)
    data.participants["pilot"] = pilot.map(lambda v: v is True or str(v).lower() in ("true", "1")).astype(bool)
    return data


def _unescape(frame: pd.DataFrame) -> pd.DataFrame:
    """Text cells as stored: the export's spreadsheet-safety prefix removed (``scenesuggest.contract.cells``)."""
    for column in frame.columns:
        values = frame[column]
        if values.dtype == object or pd.api.types.is_string_dtype(values):
            escaped = values.str.startswith("'", na=False)
            if escaped.any():
                frame.loc[escaped, column] = values[escaped].map(unescape_cell)
    return frame


#: pandas dtypes of the Table Schema types an export's ``datapackage.json`` gives its columns: text stays text ("01"
#: is not 1, "NA" is a name), integers that may be missing read as floats (NaN), as everywhere in the analysis.
_DTYPES = {"string": "str", "object": "str", "datetime": "str", "number": "float64"}
#: What exports made before they carried ``datapackage.json`` are read with: the columns known to be text.
_TEXT_BEFORE_PACKAGES = {"payload": "str", "answer": "str", "scene": "str", "condition": "str"}


def _dtype(f: dict) -> str | None:
    required = bool((f.get("constraints") or {}).get("required"))
    if f.get("type") == "integer":
        return "int64" if required else "float64"
    if f.get("type") == "boolean":
        return "bool" if required else "boolean"
    return _DTYPES.get(f.get("type"))


def _column_types(folder: Path) -> dict[str, dict[str, str]]:
    """Table → column → pandas dtype, from the export's ``datapackage.json`` (its Table Schemas); for an export made
    before it, the columns known to be text."""
    path = folder / "datapackage.json"
    if not path.exists():
        return {name: dict(_TEXT_BEFORE_PACKAGES) for name in REQUIRED}
    try:
        package = json.loads(path.read_text(encoding="utf-8"))
        return {r["name"]: {f["name"]: d for f in r["schema"]["fields"] if (d := _dtype(f)) is not None}
                for r in package["resources"]}
    except (ValueError, KeyError, TypeError) as e:
        raise AnalysisError(f"is not a data package this reader knows ({type(e).__name__}: {e})", str(path)) from None


def read_export(folder: str | Path) -> StudyData:
    """Read the CSV tables and ``manifest.json`` of an export folder, each column of the type the export's
    ``datapackage.json`` gives it."""
    folder = Path(folder)
    if not folder.is_dir():
        raise AnalysisError("is not a folder (expected the output of `scenesuggest study export`)", str(folder))
    tables, types = {}, _column_types(folder)
    for name in REQUIRED:
        path = folder / f"{name}.csv"
        if not path.exists():
            raise AnalysisError("is missing from the export", str(path))
        try:
            frame = pd.read_csv(path, dtype=types.get(name, {}), keep_default_na=False, na_values=[""])
        except (pd.errors.ParserError, ValueError) as e:  # (a ParserError is a ValueError: which one, say)
            packaged = (folder / "datapackage.json").exists()
            what = "does not hold the types its datapackage.json gives its columns" if packaged and not \
                isinstance(e, pd.errors.ParserError) else "is not valid CSV"
            raise AnalysisError(f"{what} ({e})", str(path)) from None
        tables[name] = _check_columns(name, _unescape(frame))
    manifest_path = folder / "manifest.json"
    manifest = json.loads(manifest_path.read_text()) if manifest_path.exists() else {}
    manifest["source"] = str(folder)
    scenes_path = folder / "scenes.json"
    try:
        scenes = json.loads(scenes_path.read_text()) if scenes_path.exists() else {}
    except ValueError as e:
        raise AnalysisError(f"is not valid JSON ({e})", str(scenes_path)) from None
    return _normalise(StudyData(**tables, manifest=manifest, scenes=scenes))


def _mask(url: str) -> str:
    from sqlalchemy.engine import make_url

    return make_url(url).render_as_string(hide_password=True)


def read_database(url: str, study: str | None = None) -> StudyData:
    """Read one study's tables straight from the server's database (SQLite or PostgreSQL URL)."""
    from sqlalchemy import create_engine, inspect, text
    from sqlalchemy.exc import SQLAlchemyError

    try:
        engine = create_engine(url)
    except (SQLAlchemyError, ValueError) as e:
        raise AnalysisError(f"not a database URL ({e})", "--db") from None
    try:
        with engine.connect() as con:
            scored = "score" in {c["name"] for c in inspect(con).get_columns("trials")}
            studies = pd.read_sql(text("SELECT id, title, hash FROM studies ORDER BY id"), con)
            if study is None:
                if len(studies) != 1:
                    raise AnalysisError(f"the database holds {len(studies)} studies "
                                        f"({', '.join(studies['id'])}); choose one with --study", "--db")
                study = studies["id"].iloc[0]
            elif study not in set(studies["id"]):
                raise AnalysisError(f"no study {study!r} in the database ({', '.join(studies['id'])})", "--study")
            q = {"s": study}
            columns = {c["name"] for c in inspect(con).get_columns("participants")}
            extra = "".join(f", {c}" for c in ("language", "pilot") if c in columns)  # (added by later versions)
            people = pd.read_sql(text("SELECT id AS participant, status, row, excluded_reason, created_at, "
                                      "finished_at" + extra + " FROM participants WHERE study_id = :s ORDER BY id"),
                                 con, params=q)
            trials = pd.read_sql(text(
                "SELECT t.participant_id AS participant, t.position, t.\"index\" AS trial, t.kind, t.condition, "
                "t.scene_id AS scene, t.period, t.block, t.started_at, t.done_at"
                + (", t.score" if scored else "") + " FROM trials t JOIN participants p "
                "ON p.id = t.participant_id WHERE p.study_id = :s ORDER BY t.participant_id, t.position"),
                con, params=q)
            events = pd.read_sql(text(
                "SELECT e.participant_id AS participant, e.seq, e.type, e.trial, e.client_t AS client_t_ms, "
                "e.payload FROM events e JOIN participants p ON p.id = e.participant_id WHERE p.study_id = :s "
                "ORDER BY e.participant_id, e.seq"), con, params=q)
            answers = pd.read_sql(text(
                "SELECT r.participant_id AS participant, r.survey, r.answers FROM surveys r JOIN participants p "
                "ON p.id = r.participant_id WHERE p.study_id = :s ORDER BY r.participant_id"), con, params=q)
    except SQLAlchemyError as e:
        raise AnalysisError(f"cannot read the study tables ({type(e).__name__}: {str(e).splitlines()[0]})",
                            _mask(url)) from None
    finally:
        engine.dispose()
    survey = [{"participant": r.participant, "survey": r.survey, "question": q, "answer": a}
              for r in answers.itertuples() for q, a in _decode(r.answers).items()]
    survey = pd.DataFrame(survey, columns=REQUIRED["survey"])
    title = studies.set_index("id").loc[study]
    manifest = {"study": study, "title": title["title"], "study_hash": title["hash"], "source": _mask(url)}
    return _normalise(StudyData(people, trials, events, survey, manifest))


def read_study(export: str | Path | None = None, db: str | None = None, study: str | None = None) -> StudyData:
    if (export is None) == (db is None):
        raise AnalysisError("give exactly one of --export DIR or --db URL")
    return read_export(export) if export is not None else read_database(db, study)
