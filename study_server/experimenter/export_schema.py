"""What an export's tables hold, described once and rendered twice: as the Markdown data dictionary people read
(``data_dictionary.md``) and as a Frictionless Data Package tools read (``datapackage.json``: a Table Schema per CSV
with types, units in the descriptions, primary and foreign keys, allowed values and missing values, plus the
Psych-DS / schema.org dataset metadata — name, description, ``variableMeasured``).

Every column names its Table Schema type (``integer``, ``number``, ``string``, ``boolean``, ``datetime`` — naive ISO
8601 in UTC — or ``object``, JSON text of an object); an empty cell is a missing value. Allowed values that depend on
the study (its conditions, scenes, surveys) are filled in from the study when the package is written.
"""

from __future__ import annotations

from dataclasses import dataclass

from scenesuggest.contract.cells import safe_cell
from scenesuggest.contract.events import VERSIONS, VOCABULARY
from scenesuggest.contract.scoring import FORMULA

from ..studies.study_file import Study

#: The value every table writes for a missing cell.
MISSING = ""
STATUSES = ("in_progress", "completed", "no_consent", "screened_out", "returned", "excluded", "technical")
STEPS = ("device", "consent", "demographics", "instructions", "trial", "exit", "done")
PLATFORMS = ("prolific", "mturk", "link")
#: Allowed values taken from the study when the package is written: key → what of the study (to which the ids the
#: data holds are added: a study file changed after collection began still describes its data).
STUDY_VALUES = {"conditions": lambda s: [c.id for c in s.conditions], "scenes": lambda s: list(s.scenes),
                "languages": lambda s: list(s.languages)}


@dataclass(frozen=True)
class Column:
    """One column: its name, Table Schema type, meaning (units said in it), whether every row has a value, and its
    allowed values (a tuple, or a key of :data:`STUDY_VALUES`)."""

    name: str
    type: str
    description: str
    required: bool = False
    enum: tuple | str = ()
    minimum: int | float | None = None


@dataclass(frozen=True)
class Table:
    name: str
    description: str
    columns: tuple[Column, ...]
    primary_key: tuple[str, ...] = ()
    #: Columns that name a participant of participants.csv.
    participant_key: bool = True


def _c(name, type_, description, **kw) -> Column:
    return Column(name, type_, description, **kw)


PARTICIPANT = _c("participant", "integer", "participant number (database id)", required=True)
UTC = " (UTC, ISO 8601)"

TABLES: tuple[Table, ...] = (
    Table("participants", "one row per participant who arrived", (
        PARTICIPANT,
        _c("study", "string", "study id", required=True),
        _c("study_hash", "string", "sha256 of the study file", required=True),
        _c("platform", "string", "where the participant came from", required=True, enum=PLATFORMS),
        _c("platform_id", "string", "the platform's worker id", required=True),
        _c("row", "integer", "schedule row (Williams row × period) assigned at consent; −1 before consent",
           required=True, minimum=-1),
        _c("status", "string", "how the session stands or ended", required=True, enum=STATUSES),
        _c("step", "string", "last step reached", required=True, enum=STEPS),
        _c("consent_version", "string", "consent text version agreed to"),
        _c("excluded_reason", "string", "why an experimenter excluded the participant"),
        _c("created_at", "datetime", "arrival" + UTC, required=True),
        _c("last_seen_at", "datetime", "last request" + UTC, required=True),
        _c("finished_at", "datetime", "completion or early end" + UTC),
        _c("acked_seq", "integer", "highest contiguous event seq stored (−1: none)", required=True, minimum=-1),
        _c("flags", "string", "why the experimenter should review this participant (reasons separated by ' | '; "
                              "empty: none; flags the experimenter cleared are not listed)"),
        _c("viewport_width", "integer", "browser window width at the device check (px)"),
        _c("viewport_height", "integer", "browser window height at the device check (px)"),
        _c("device_fps", "number", "frames per second the editor's renderer drew at the device check (empty: not "
                                   "measured)", minimum=0),
        _c("device_renderer", "string", "the WebGL renderer the browser named at the device check"),
        _c("screened_out_reasons", "string", "why the device check screened the browser out (codes separated by "
                                             "' | ': script, modules, importmap, storage, pointer_events, "
                                             "resize_observer, dialog, webgl2, shaders, desktop, window, slow; "
                                             "empty: it passed or was not checked)"),
        _c("user_agent", "string", "browser user agent"),
        _c("language", "string", "the language the participant's pages spoke (chosen at arrival among the study's "
                                 "languages)", enum="languages"),
        _c("pilot", "boolean", "a pilot: the experimenter's test run or a simulated participant (arrived through an "
                               "entry link signed with the server's key), not study data; the report leaves pilots "
                               "out when the data hold anyone else", required=True),
    ), ("participant",), participant_key=False),
    Table("trials", "one row per trial of a participant's plan (the practice trial first, when the study has one)", (
        PARTICIPANT,
        _c("position", "integer", "order in the session (0 = first)", required=True, minimum=0),
        _c("trial", "integer", "trial index (−1 = practice)", required=True, minimum=-1),
        _c("kind", "string", "practice or a counted trial", required=True, enum=("practice", "trial")),
        _c("condition", "string", "the interface: none (a fixed list and search), basic (suggestions), full "
                                  "(oriented suggestions)", required=True, enum="conditions"),
        _c("scene", "string", "target scene id", required=True, enum="scenes"),
        _c("period", "integer", "period of the schedule row", required=True, minimum=0),
        _c("block", "integer", "block within the session (−1: the practice)", required=True, minimum=-1),
        _c("started_at", "datetime", "trial page first shown" + UTC),
        _c("done_at", "datetime", "done acknowledged" + UTC),
        _c("briefing_seconds", "number", "seconds the page of the condition's instructions was open before the trial "
                                         "(shown before the first trial and wherever the condition changes; server "
                                         "clock; not part of the trial's time; empty: none was shown)", minimum=0),
        _c("final_objects", "integer", "objects in the final scene", minimum=0),
        _c("review", "string", "why the trial should be reviewed: its events do not show the study's minimum work, "
                               "or its scene came less close to the target than [limits] min_target_score (empty: "
                               "neither)"),
        _c("replay", "string", "whether the trial's events rebuild the final scene it submitted: match, mismatch: "
                               "what differs, pending: (events the page logged before 'done' not stored yet; made "
                               "at the next 'done' or at completion, then with '(events after seq N never "
                               "arrived)' if some never did), or unavailable: why (events of vocabulary 1 carry no "
                               "object states, or the check failed)"),
        _c("score", "number", "how close the final scene came to the target, 0..1, as the server found it when the "
                              "trial was done (this and the next five columns are stored then and exported as "
                              f"stored): {FORMULA}", minimum=0),
        _c("matched", "integer", "target objects matched by an object of the final scene", minimum=0),
        _c("missing", "integer", "target objects nothing matched", minimum=0),
        _c("extra", "integer", "objects of the final scene that match nothing", minimum=0),
        _c("position_error_m", "number", "mean distance of the matched objects from their targets (metres)",
           minimum=0),
        _c("orientation_error_deg", "number", "mean angle of the matched objects from their targets' orientations, "
                                              "folded by each model's rotational symmetry (degrees)", minimum=0),
    ), ("participant", "position")),
    Table("events", "one row per logged interaction event, as the page sent it", (
        PARTICIPANT,
        _c("seq", "integer", "per-participant event number from 0, without gaps", required=True, minimum=0),
        _c("page_id", "string", "page load that sent it", required=True),
        _c("type", "string", "event type (the event vocabulary: event_schema.json)", required=True,
           enum=tuple(sorted(VOCABULARY))),
        _c("trial", "integer", "trial index (−1 = practice; empty: outside a trial)", minimum=-1),
        _c("client_t_ms", "number", "client clock, ms since the epoch", required=True),
        _c("server_t", "datetime", "server receive time" + UTC, required=True),
        _c("payload", "object", "event payload as JSON (its fields: event_schema.json)", required=True),
        _c("vocabulary", "integer", "version of the event vocabulary the page spoke (2: scene changes carry the "
                                    "resulting object states; see event_schema.json, and event_schema_v1.json when "
                                    "the data holds version 1)", required=True, enum=VERSIONS),
    ), ("participant", "seq")),
    Table("suggestions", "one row per item of a list the server showed: context suggestions and search results", (
        PARTICIPANT,
        _c("list_id", "string", "id of the list", required=True),
        _c("trial", "integer", "trial index (empty: outside a trial)", minimum=-1),
        _c("source", "string", "context (suggestions for a click) or search (a keyword search)", required=True,
           enum=("context", "search")),
        _c("rank", "integer", "1-based rank in the list", required=True, minimum=1),
        _c("category", "string", "category"),
        _c("model", "string", "model id (search lists) or first model of the category (context lists)"),
        _c("score", "number", "engine score (context lists; unitless, higher is better)"),
        _c("created_at", "datetime", "when the server made the list" + UTC, required=True),
        _c("query", "object", "the query as JSON (context: the clicked parent, point and normal in metres, world "
                              "frame; search: the text)", required=True),
    ), ("list_id", "rank")),
    Table("picks", "one row per model placed (insert and replace events), by the one definition of a pick", (
        PARTICIPANT,
        _c("seq", "integer", "event seq", required=True, minimum=0),
        _c("trial", "integer", "trial index", minimum=-1),
        _c("client_t_ms", "number", "client clock, ms since the epoch", required=True),
        _c("action", "string", "what placed it", required=True, enum=("insert", "replace")),
        _c("object", "string", "editor object id"),
        _c("model", "string", "model id"),
        _c("category", "string", "category"),
        _c("rank", "integer", "rank in the list it was picked from (empty if none)", minimum=1),
        _c("reciprocal_rank", "number", "1 / rank (empty if none)", minimum=0),
        _c("source", "string", "the list it came from", required=True, enum=("context", "search", "fixed")),
        _c("list_id", "string", "list it was picked from, when known"),
        _c("final", "boolean", "true unless a later pick of the trial replaced this one in place (the top "
                               "suggestion is placed at once; the participant's choice is the last pick of such a "
                               "chain; MRR counts final picks)", required=True),
    ), ("participant", "seq")),
    Table("survey", "one row per survey answer", (
        PARTICIPANT,
        _c("survey", "string", "which survey", required=True, enum=("demographics", "exit")),
        _c("question", "string", "question id (the study file's)", required=True),
        _c("answer", "string", "the answer (Likert 1..scale, choice text, number or free text)"),
    ), ("participant", "survey", "question")),
    Table("session_log", "one row per server-side observation: arrival, resume, device check, failures, …", (
        PARTICIPANT,
        _c("kind", "string", "arrive | view | resume | device_check | consent | instructions | trial_start | "
                             "trial_done | finish | error | …", required=True),
        _c("at", "datetime", "server time" + UTC, required=True),
        _c("detail", "object", "details as JSON", required=True),
    )),
)
#: Table → column → meaning, in the order the CSV files write them.
DICTIONARY: dict[str, dict[str, str]] = {t.name: {c.name: c.description for c in t.columns} for t in TABLES}


def dictionary_markdown() -> str:
    """``data_dictionary.md``: every table's columns, types and meanings, and how text cells are written."""
    lines = ["# Data dictionary", "",
             "The same description, for tools, is `datapackage.json` (a Frictionless Data Package). An empty cell is "
             "a missing value; times are UTC.", ""]
    for t in TABLES:
        lines += [f"## {t.name}.csv", "", f"{t.description[0].upper()}{t.description[1:]}"
                  + (f"; one row per ({', '.join(t.primary_key)})." if t.primary_key else "."), "",
                  "| column | type | meaning |", "|---|---|---|"]
        for c in t.columns:
            allowed = f" One of: {', '.join(map(str, c.enum))}." if isinstance(c.enum, tuple) and c.enum else ""
            lines.append(f"| {c.name} | {c.type} | {c.description.rstrip('.')}.{allowed} |")
        lines.append("")
    lines += ["## Text cells", "",
              "A text cell is written as it is when it is a number or begins with a letter, a digit or one of "
              "`{ [ \" ( # _ . / < * :`; any other text cell (one beginning with `=`, `+`, `-`, `@`, a tab, a "
              "space, a no-break space, a byte-order mark, a full-width `＝`, `|`, `'` …) is written with one "
              "leading `'` so that spreadsheets show it as text instead of running it as a formula (CSV "
              "injection: OWASP's list, and the characters spreadsheets skip before it). Remove that one "
              "`'` to get the stored value (`analysis.load.read_export` does). Text that was stored without "
              "being valid Unicode appears with backslash escapes (`\\udfff`).", ""]
    return "\n".join(lines)


def _field(c: Column, study: Study, present: dict[str, set]) -> dict:
    out = {"name": c.name, "type": c.type, "description": c.description}
    if c.type == "datetime":
        out["format"] = "%Y-%m-%dT%H:%M:%S.%f"
    if c.type == "boolean":
        out |= {"trueValues": ["true"], "falseValues": ["false"]}
    constraints = {}
    if c.required:
        constraints["required"] = True
    if isinstance(c.enum, str):
        ids = list(STUDY_VALUES[c.enum](study))
        enum = ids + sorted(present.get(c.enum, set()) - set(ids))
    else:
        enum = list(c.enum)
    if enum:  # as the cells hold them (a text that a spreadsheet would run is written escaped)
        constraints["enum"] = [safe_cell(v) for v in enum]
    if c.minimum is not None:
        constraints["minimum"] = c.minimum
    if constraints:
        out["constraints"] = constraints
    return out


def _variables() -> list[dict]:
    """Every column name the tables use, once (Psych-DS names variables as the columns' headers), with its meaning
    where it first appears and the tables that hold it."""
    tables: dict[str, list[str]] = {}
    first: dict[str, Column] = {}
    for t in TABLES:
        for c in t.columns:
            tables.setdefault(c.name, []).append(t.name)
            first.setdefault(c.name, c)
    return [{"@type": "PropertyValue", "name": name, "description": f"{first[name].description} (in "
             f"{', '.join(f'{t}.csv' for t in tables[name])})"} for name in tables]


def package_name(study_id: str) -> str:
    """A Data Package name for the study: lower case letters, digits and ``-._`` only."""
    name = "".join(ch if ch.isascii() and (ch.isalnum() or ch in "-._") else "-" for ch in study_id.lower())
    return name.strip("-") or "study"


def data_package(study: Study, files: dict[str, str], exported_at: str, present: dict[str, set] | None = None) -> dict:
    """``datapackage.json`` for an export of ``study`` whose CSV files have the SHA-256 digests ``files`` (name →
    hex) and whose data holds the ids ``present`` (``conditions``, ``scenes``: added to the study's own as allowed
    values): a Tabular Data Package, one resource per table with its schema, and the dataset's Psych-DS-style
    schema.org metadata (``variableMeasured``: every column name the tables use, once)."""
    present = present or {}
    resources = []
    for t in TABLES:
        schema = {"fields": [_field(c, study, present) for c in t.columns], "missingValues": [MISSING]}
        if t.primary_key:
            schema["primaryKey"] = list(t.primary_key)
        if t.participant_key:
            schema["foreignKeys"] = [{"fields": ["participant"],
                                      "reference": {"resource": "participants", "fields": ["participant"]}}]
        resources.append({"name": t.name, "path": f"{t.name}.csv", "profile": "tabular-data-resource",
                          "title": t.name.replace("_", " "), "description": t.description, "format": "csv",
                          "mediatype": "text/csv", "encoding": "utf-8",
                          "hash": f"sha256:{files[f'{t.name}.csv']}", "schema": schema})
    return {
        "profile": "tabular-data-package",
        "name": package_name(study.id), "title": study.title,
        "description": f"Data of the user study {study.title!r} ({study.id}) as SceneSuggest Studio recorded it: "
                       "participants, their trials under the interface conditions, every interaction event, the "
                       "lists the server showed, the models placed, survey answers and the server's session log.",
        "created": exported_at,
        "resources": resources,
        # Psych-DS (schema.org Dataset) metadata
        "@context": "https://schema.org/", "@type": "Dataset",
        "variableMeasured": _variables(),
    }
