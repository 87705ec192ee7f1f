"""Study files: TOML, validated with errors that name the key (``conditions[1].engine``).

Paths inside a study file are relative to the file. See ``study_server/demo/study.toml`` for every key.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from scenesuggest import engines
from scenesuggest.errors import SceneSuggestError

from ..base.config import data_home
from ..base.i18n import Text, shipped
from . import schedule
from .toml_reader import Reader, StudyFileError, parse

__all__ = ["Condition", "Question", "Study", "StudyFileError", "TargetScene", "load_study"]

CONDITIONS = ("none", "basic", "full")
DESIGNS = ("williams", "random", "fixed")
BLOCKINGS = ("condition", "scene")
PLATFORMS = ("prolific", "mturk", "link")
CODES = ("complete", "no_consent", "screened_out", "returned", "technical")
#: Codes a study file may leave out (older study files have none for participants who leave).
OPTIONAL_CODES = ("returned",)
#: Where Prolific takes a completion code (its one completion URL, the code as ``cc``).
PROLIFIC_COMPLETION = "https://app.prolific.com/submissions/complete?cc={code}"
QUESTION_KINDS = ("likert", "choice", "number", "text")


@dataclass(frozen=True)
class Condition:
    """A condition: its interface (``id``: none, basic or full), texts, and the engine that suggests in it (a
    registered engine by name, with its options; see :mod:`scenesuggest.engines`)."""

    id: str
    label: str
    instructions: str
    engine: engines.EngineSpec

    @property
    def mode(self) -> str | None:
        """The engine's mode in this interface — ``basic`` (placed as geometry says) or ``full`` (placed and turned
        as the priors say) — or None: ``none`` has no suggestions."""
        return None if self.id == "none" else self.id


@dataclass(frozen=True)
class TargetScene:
    id: str
    title: str
    target: Path
    start: Path | None


@dataclass(frozen=True)
class Question:
    id: str
    kind: str
    label: str
    required: bool = True
    options: tuple[str, ...] = ()
    scale: int = 5
    low: str = ""
    high: str = ""
    minimum: float | None = None
    maximum: float | None = None


@dataclass(frozen=True)
class Study:
    path: Path
    hash: str
    id: str
    title: str
    description: str
    corpus: str
    priors: Path
    library: Path
    #: the priors and library are the server's own for the corpus (the file names neither; see _resources)
    server_resources: bool
    design: str
    blocking: str
    participants: int
    conditions: tuple[Condition, ...]
    scenes: dict[str, TargetScene]
    periods: tuple[tuple[str, ...], ...]
    practice: tuple[str, str] | None
    platform: str
    codes: dict[str, str]
    completion_url: str | None
    consent_version: str
    consent_text: str
    instructions: tuple[tuple[str, str], ...]
    demographics: tuple[Question, ...]
    exit_survey: tuple[Question, ...]
    trial_minutes: float
    session_minutes: float
    stale_after_minutes: float
    desktop_only: bool
    min_width: int
    min_height: int
    #: The device check's lowest frame rate (frames per second of the editor's renderer on a small scene; 0: none).
    min_fps: float = 10.0
    #: Prolific's id of this study: arrivals whose STUDY_ID differs are refused (None: not checked).
    platform_study_id: str | None = None
    #: What a trial's events must show for it to count as work (else the participant is flagged for review):
    #: objects placed (insert/replace events) and seconds between its first and last event (client clock).
    min_objects_placed: int = 0
    min_trial_seconds: float = 0.0
    #: Trials whose final scene scores below this (scenesuggest.contract.scoring, 0..1) are flagged for review.
    min_target_score: float | None = None
    #: Quotas: new arrivals per client address per hour; events and megabytes stored per participant.
    arrivals_per_address_per_hour: int = 100
    max_events_per_participant: int = 100_000
    max_mb_per_participant: float = 32.0
    #: The languages the study speaks, its default first (its texts are :class:`study_server.base.i18n.Text`).
    languages: tuple[str, ...] = ("en",)

    def condition(self, condition_id: str) -> Condition:
        return next(c for c in self.conditions if c.id == condition_id)

    @property
    def n_rows(self) -> int:
        return schedule.n_rows(self.design, len(self.conditions), len(self.periods))

    def plan(self, row: int, seed: int = 0) -> list[schedule.PlannedTrial]:
        return schedule.plan(self.design, self.blocking, [c.id for c in self.conditions],
                             [list(p) for p in self.periods], row, seed, self.practice)


def _languages(r: Reader, doc: dict) -> tuple[str, ...]:
    """The study's languages, its default first: ``language = "de"`` (one) or ``languages = ["en", "de"]`` (the
    participant's browser chooses); English when it says neither. Each must be one this server has a catalogue of."""
    if "language" in doc and "languages" in doc:
        raise r.fail("languages", "give either language (one) or languages (several), not both")
    if "language" in doc:
        found, where = [r.string(doc, "language", "language")], ["language"]
    else:
        found = doc.get("languages", ["en"])
        if not isinstance(found, list) or not found or not all(isinstance(x, str) for x in found):
            raise r.fail("languages", "expected a list of language codes, e.g. [\"en\", \"de\"]")
        where = [f"languages[{i}]" for i in range(len(found))]
    speaks = shipped()
    for code, key in zip(found, where, strict=True):
        if code not in speaks:
            raise r.fail(key, f"no catalogue for the language {code!r} (this server speaks {', '.join(speaks)})")
    if len(set(found)) != len(found):
        raise r.fail("languages", "a language is given twice")
    return tuple(found)


def _text(r: Reader, doc: dict, key: str, path: str, languages: tuple[str, ...], default: str | None = None) -> Text:
    """A study text: a string in the study's one language, or a table with one string per language of the study
    (``label = { en = "…", de = "…" }``); the first language's is the text itself. A text that is wrong is recorded
    (:meth:`Reader.attempt`) and reading goes on."""
    return r.attempt(lambda: _read_text(r, doc, key, path, languages, default), Text("?"))


def _read_text(r: Reader, doc: dict, key: str, path: str, languages: tuple[str, ...] | None,
               default: str | None) -> Text:
    if languages is None:  # the study's languages are wrong (recorded): a wrong language is not reported again here
        if key not in doc and default is None:
            raise r.fail(path, "missing")
        value = doc.get(key, default)
        value = next((v for v in value.values() if isinstance(v, str)), "?") if isinstance(value, dict) else value
        return Text(value if isinstance(value, str) else "?")
    if key not in doc and default is not None:  # an optional text left out: its default in every language
        return Text(default, dict.fromkeys(languages, default))
    value = doc.get(key, default)
    if isinstance(value, dict):
        for lang in value:
            if lang not in languages:
                raise r.fail(f"{path}.{lang}", f"not one of the study's languages ({', '.join(languages)})")
        for lang in languages:
            if not isinstance(value.get(lang), str) or not value[lang].strip():
                raise r.fail(f"{path}.{lang}", f"missing: the text in {lang!r}, a language of the study"
                             if lang not in value else "expected a non-empty string")
        return Text(value[languages[0]], {lang: value[lang] for lang in languages})
    if len(languages) > 1:
        if not isinstance(value, str):
            raise r.fail(path, "missing" if key not in doc else "expected a table with one string per language")
        raise r.fail(path, f"the study speaks {', '.join(languages)}: give this text in each, as "
                           f"{{ {', '.join(f'{lang} = …' for lang in languages)} }}")
    if not isinstance(value, str) or not value.strip():
        raise r.fail(path, "missing" if key not in doc else "expected a non-empty string")
    return Text(value, {languages[0]: value})


def _questions(r: Reader, items: list[dict], path: str, languages: tuple[str, ...]) -> tuple[Question, ...]:
    out, seen = [], set()
    for i, q in enumerate(items):
        question = r.attempt(lambda i=i, q=q: _question(r, q, f"{path}[{i}]", languages, seen))
        if question is not None:
            out.append(question)
    return tuple(out)


def _question(r: Reader, q: dict, p: str, languages: tuple[str, ...], seen: set) -> Question:
    """One survey question (its id added to ``seen``)."""
    r.unknown(q, ("id", "kind", "label", "required", "options", "scale", "low", "high", "min", "max"), p)
    qid = r.string(q, "id", f"{p}.id")
    if qid in seen:
        raise r.fail(f"{p}.id", f"duplicate question id {qid!r}")
    seen.add(qid)
    kind = r.choice(q, "kind", f"{p}.kind", QUESTION_KINDS)
    options = q.get("options", [])
    if kind == "choice" and (not isinstance(options, list) or len(options) < 2
                             or not all(isinstance(o, str | dict) and o for o in options)):
        raise r.fail(f"{p}.options", "a choice question needs at least two options")
    # an answer is stored as the option in the study's default language, whatever the page showed
    options = tuple(_text(r, {"o": o}, "o", f"{p}.options[{j}]", languages) for j, o in enumerate(options)) \
        if kind == "choice" else ()
    scale = int(r.number(q, "scale", f"{p}.scale", 5, minimum=2)) if kind == "likert" else 5
    ends = {end: _text(r, q, end, f"{p}.{end}", languages) if end in q else "" for end in ("low", "high")}
    return Question(qid, kind, _text(r, q, "label", f"{p}.label", languages),
                    r.boolean(q, "required", f"{p}.required", True), options, scale, ends["low"], ends["high"],
                    r.number(q, "min", f"{p}.min", minimum=-1e12) if "min" in q else None,
                    r.number(q, "max", f"{p}.max", minimum=-1e12) if "max" in q else None)


def _engine(r: Reader, doc: dict, path: str, base: Path) -> engines.EngineSpec:
    """The condition's engine: ``name`` (default ``paper``) and the options its kind takes (errors name the key)."""
    try:
        return engines.configure(doc, base)
    except SceneSuggestError as e:
        raise r.fail(f"{path}.{e.field}" if e.field else path, e.message) from None


def _conditions(r: Reader, doc: dict, base: Path, languages: tuple[str, ...]) -> tuple[list[Condition], bool]:
    """The conditions, and whether every one has a valid id; one with a problem is recorded and stands in by its id
    (what later keys refer to), so that only a wrong id makes what refers to conditions uncheckable."""
    conditions: list[Condition] = []
    tables = r.attempt(lambda: r.tables(doc, "conditions", "conditions"))
    whole = tables is not None
    for i, c in enumerate(tables or []):
        p = f"conditions[{i}]"
        cid = r.attempt(lambda c=c, p=p: r.choice(c, "id", f"{p}.id", CONDITIONS))
        if cid is None:
            whole = False
            continue
        if any(x.id == cid for x in conditions):
            r.record(r.fail(f"{p}.id", f"condition {cid!r} given twice"))
            continue
        conditions.append(r.attempt(lambda c=c, p=p, cid=cid: _condition(r, c, p, cid, base, languages),
                                    Condition(cid, cid, "", None)))
    return conditions, whole


def _condition(r: Reader, c: dict, p: str, cid: str, base: Path, languages: tuple[str, ...]) -> Condition:
    r.attempt(lambda: r.unknown(c, ("id", "label", "instructions", "engine"), p))
    instructions = _text(r, c, "instructions", f"{p}.instructions", languages) if "instructions" in c else ""
    return Condition(cid, _text(r, c, "label", f"{p}.label", languages, cid), instructions,
                     _engine(r, r.table(c, "engine", f"{p}.engine", required=False), f"{p}.engine", base))


def _scenes(r: Reader, doc: dict, base: Path, languages: tuple[str, ...]) -> tuple[dict[str, TargetScene], bool]:
    """The target scenes, and whether every one has an id; one with a problem is recorded and stands in by its id
    (what the periods and the practice refer to)."""
    tables = r.attempt(lambda: r.tables(doc, "scenes", "scenes"))
    scenes, whole = {}, tables is not None
    for i, s in enumerate(tables or []):
        p = f"scenes[{i}]"
        sid = r.attempt(lambda s=s, p=p: r.string(s, "id", f"{p}.id"))
        if sid is None:
            whole = False
            continue
        scenes[sid] = r.attempt(lambda s=s, p=p, sid=sid: _scene(r, s, p, sid, base, languages),
                                TargetScene(sid, sid, Path(), None))
    return scenes, whole


def _scene(r: Reader, s: dict, p: str, sid: str, base: Path, languages: tuple[str, ...]) -> TargetScene:
    r.attempt(lambda: r.unknown(s, ("id", "title", "target", "start"), p))
    target = base / r.string(s, "target", f"{p}.target")
    if not target.is_file():
        raise r.fail(f"{p}.target", f"no such file: {target}")
    start = base / s["start"] if "start" in s else None
    if start is not None and not start.is_file():
        raise r.fail(f"{p}.start", f"no such file: {start}")
    return TargetScene(sid, _text(r, s, "title", f"{p}.title", languages, sid), target, start)


def _periods(r: Reader, doc: dict, scenes: dict | None) -> list[tuple[str, ...]]:
    """The periods' scene ids (each checked against ``scenes``; None: the scenes could not all be read)."""
    periods = []
    for i, per in enumerate(r.attempt(lambda: r.tables(doc, "periods", "periods"), [])):
        period = r.attempt(lambda i=i, per=per: _period(r, per, f"periods[{i}]", scenes))
        if period is not None:
            periods.append(period)
    return periods


def _period(r: Reader, per: dict, p: str, scenes: dict | None) -> tuple[str, ...]:
    r.unknown(per, ("scenes",), p)
    ids = per.get("scenes")
    if not isinstance(ids, list) or not ids:
        raise r.fail(f"{p}.scenes", "expected a list of scene ids")
    for j, sid in enumerate(ids):
        if scenes is not None and sid not in scenes:
            raise r.fail(f"{p}.scenes[{j}]", f"no scene {sid!r} in [[scenes]]")
    if len(set(ids)) != len(ids):
        raise r.fail(f"{p}.scenes", "a scene appears twice")
    return tuple(ids)


def _practice(r: Reader, doc: dict, scenes: dict | None, conditions: list[Condition] | None
              ) -> tuple[str, str] | None:
    """The practice trial's scene and condition (each checked against ``scenes`` and ``conditions``; None: those
    could not all be read)."""
    practice_doc = r.table(doc, "practice", "practice", required=False)
    if not practice_doc:
        return None
    r.unknown(practice_doc, ("scene", "condition"), "practice")
    sid = r.string(practice_doc, "scene", "practice.scene")
    if scenes is not None and sid not in scenes:
        raise r.fail("practice.scene", f"no scene {sid!r} in [[scenes]]")
    return sid, r.choice(practice_doc, "condition", "practice.condition",
                         [c.id for c in conditions] if conditions is not None else CONDITIONS)


def _platform(r: Reader, doc: dict) -> dict:
    platform = r.table(doc, "platform", "platform")
    r.unknown(platform, ("kind", "codes", "completion_url", "study_id"), "platform")
    codes_doc = r.table(platform, "codes", "platform.codes")
    r.unknown(codes_doc, CODES, "platform.codes")
    completion_url = platform.get("completion_url")
    if completion_url is not None and (not isinstance(completion_url, str) or "{code}" not in completion_url
                                       or not completion_url.startswith(("https://", "http://"))):
        raise r.fail("platform.completion_url", "expected an http(s) URL containing {code}")
    kind = r.choice(platform, "kind", "platform.kind", PLATFORMS)
    if completion_url is None and kind == "prolific":
        completion_url = PROLIFIC_COMPLETION
    return {"platform": kind,
            "codes": {k: r.attempt(lambda k=k: r.string(codes_doc, k, f"platform.codes.{k}"), "?") for k in CODES
                      if k in codes_doc or k not in OPTIONAL_CODES},
            "completion_url": completion_url,
            "platform_study_id": r.string(platform, "study_id", "platform.study_id") if "study_id" in platform
            else None}


def _texts(r: Reader, doc: dict, languages: tuple[str, ...]) -> dict:
    """Consent, instructions and surveys, in each of the study's languages."""
    consent = r.attempt(lambda: r.table(doc, "consent", "consent"))
    if consent is None:  # recorded; its keys are not read (each would be "missing" again)
        version, text = "?", Text("?")
    else:
        r.attempt(lambda: r.unknown(consent, ("version", "text"), "consent"))
        version = r.attempt(lambda: r.string(consent, "version", "consent.version"), "?")
        text = _text(r, consent, "text", "consent.text", languages)
    instructions = []
    for i, page in enumerate(r.attempt(lambda: r.tables(doc, "instructions", "instructions"), [])):
        r.attempt(lambda i=i, page=page: r.unknown(page, ("title", "body"), f"instructions[{i}]"))
        instructions.append((_text(r, page, "title", f"instructions[{i}].title", languages),
                             _text(r, page, "body", f"instructions[{i}].body", languages)))
    return {"consent_version": version, "consent_text": text, "instructions": tuple(instructions),
            "demographics": _questions(r, doc.get("demographics", []) or [], "demographics", languages),
            "exit_survey": _questions(r, r.attempt(lambda: r.tables(doc, "exit_survey", "exit_survey"), []),
                                      "exit_survey", languages)}


LIMITS = ("trial_minutes", "session_minutes", "stale_after_minutes", "min_objects_placed", "min_trial_seconds",
          "min_target_score", "arrivals_per_address_per_hour", "max_events_per_participant", "max_mb_per_participant")


def _score(r: Reader, limits: dict) -> float | None:
    """``min_target_score``: trials whose scene comes less close to the target are flagged (none when absent)."""
    if "min_target_score" not in limits:
        return None
    value = r.number(limits, "min_target_score", "limits.min_target_score")
    if value > 1:
        raise r.fail("limits.min_target_score", "expected a score from 0 to 1")
    return value


def _limits(r: Reader, doc: dict) -> dict:
    """Time limits, the minimum work of a trial, quotas, and the device check."""
    limits = r.attempt(lambda: r.table(doc, "limits", "limits", required=False), {})
    r.attempt(lambda: r.unknown(limits, LIMITS, "limits"))
    device = r.attempt(lambda: r.table(doc, "device", "device", required=False), {})
    r.attempt(lambda: r.unknown(device, ("desktop_only", "min_width", "min_height", "min_fps"), "device"))

    def number(key: str, default: float, minimum: float = 0.0) -> float:
        return r.attempt(lambda: r.number(limits, key, f"limits.{key}", default, minimum=minimum), default)

    return {
        "trial_minutes": number("trial_minutes", 15, 0.1), "session_minutes": number("session_minutes", 90, 0.1),
        "stale_after_minutes": number("stale_after_minutes", 5, 0.1),
        "min_objects_placed": int(number("min_objects_placed", 0)),
        "min_trial_seconds": number("min_trial_seconds", 0),
        "min_target_score": r.attempt(lambda: _score(r, limits)),
        "arrivals_per_address_per_hour": int(number("arrivals_per_address_per_hour", 100, 1)),
        "max_events_per_participant": int(number("max_events_per_participant", 100_000, 100)),
        "max_mb_per_participant": number("max_mb_per_participant", 32, 0.1),
        "desktop_only": r.attempt(lambda: r.boolean(device, "desktop_only", "device.desktop_only", True), True),
        "min_width": int(r.attempt(lambda: r.number(device, "min_width", "device.min_width", 1024), 1024)),
        "min_height": int(r.attempt(lambda: r.number(device, "min_height", "device.min_height", 600), 600)),
        "min_fps": r.attempt(lambda: r.number(device, "min_fps", "device.min_fps", 10, maximum=120), 10),
    }


#: Corpora whose scenes and models come with the package, so the server can build their priors and library itself.
SERVER_BUILT_CORPORA = ("ai2thor",)


def _resources(r: Reader, doc: dict, base: Path) -> dict:
    """The corpus, and the priors file and model library: both named (paths relative to the study file), or
    neither, for a corpus the server builds them for itself (``priors/<corpus>.npz`` and ``library/<corpus>``
    in its data folder, :func:`..base.config.data_home`; ``scenesuggest study prepare`` builds them)."""
    res = r.table(doc, "resources", "resources")
    r.unknown(res, ("corpus", "priors", "library"), "resources")
    corpus = r.string(res, "corpus", "resources.corpus")
    named = [k for k in ("priors", "library") if k in res]
    if len(named) == 1:
        other = "library" if named == ["priors"] else "priors"
        raise r.fail(f"resources.{other}", f"missing: name both the priors file and the model library, or "
                                           f"neither (for {', '.join(SERVER_BUILT_CORPORA)})")
    if named:
        return {"corpus": corpus, "priors": base / r.string(res, "priors", "resources.priors"),
                "library": base / r.string(res, "library", "resources.library"), "server_resources": False}
    if corpus not in SERVER_BUILT_CORPORA:
        raise r.fail("resources.priors", f"missing: the corpus {corpus!r} needs its priors file and model library "
                                         f"named (the server builds its own for {', '.join(SERVER_BUILT_CORPORA)} "
                                         "only)")
    home = data_home()
    return {"corpus": corpus, "priors": home / "priors" / f"{corpus}.npz", "library": home / "library" / corpus,
            "server_resources": True}


def load_study(path: str | Path) -> Study:
    """Read and validate a study file; every problem names its key, and one reading names every problem it can
    (:class:`study_server.studies.toml_reader.StudyFileErrors`: a part with a problem stands in by what later parts
    refer to, so that one mistake is not reported again as another)."""
    path = Path(path).resolve()
    data, doc = parse(path)
    r = Reader(path, data.decode("utf-8"))
    base = path.parent
    r.attempt(lambda: r.unknown(doc, ("id", "title", "description", "resources", "design", "conditions", "scenes",
                                      "periods", "practice", "platform", "consent", "instructions", "demographics",
                                      "exit_survey", "limits", "device", "language", "languages"), ""))
    study_id = r.attempt(lambda: _study_id(r, doc), "?")
    languages = r.attempt(lambda: _languages(r, doc))  # None when wrong: the texts are then read unchecked
    conditions, conditions_whole = _conditions(r, doc, base, languages)
    scenes, scenes_whole = _scenes(r, doc, base, languages)
    periods = _periods(r, doc, scenes if scenes_whole else None)
    fields = {
        "title": _text(r, doc, "title", "title", languages),
        "description": _text(r, doc, "description", "description", languages) if "description" in doc else "",
        **_design(r, doc),
        "practice": r.attempt(lambda: _practice(r, doc, scenes if scenes_whole else None,
                                                conditions if conditions_whole else None)),
        **(r.attempt(lambda: _resources(r, doc, base), {})), **(r.attempt(lambda: _platform(r, doc), {})),
        **_texts(r, doc, languages), **_limits(r, doc)}
    if fields["design"] == "williams" and conditions_whole and len(conditions) < 2:
        r.record(r.fail("design.kind", "a Williams design needs at least two conditions"))
    r.finish()
    return Study(path=path, hash=hashlib.sha256(data).hexdigest(), id=study_id, languages=languages,
                 conditions=tuple(conditions), scenes=scenes, periods=tuple(periods), **fields)


def _design(r: Reader, doc: dict) -> dict:
    """The design's kind, blocking and planned number of participants (none read when the table is wrong)."""
    design = r.attempt(lambda: r.table(doc, "design", "design"))
    if design is None:
        return {"design": None, "blocking": None, "participants": None}
    r.attempt(lambda: r.unknown(design, ("kind", "blocking", "participants"), "design"))
    return {"design": r.attempt(lambda: r.choice(design, "kind", "design.kind", DESIGNS)),
            "blocking": r.attempt(lambda: r.choice(design, "blocking", "design.blocking", BLOCKINGS, "condition")),
            "participants": r.attempt(lambda: int(r.number(design, "participants", "design.participants",
                                                           minimum=1)))}


def _study_id(r: Reader, doc: dict) -> str:
    study_id = r.string(doc, "id", "id")
    if not study_id.replace("-", "").replace("_", "").isalnum():
        raise r.fail("id", "use letters, digits, '-' and '_' only")
    return study_id
