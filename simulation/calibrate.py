"""Calibrating the simulated participants on some of the paper's conditions, and predicting the rest.

The free parameters of :class:`~.human.Human` are fitted so that bots rebuilding the study's targets in the
conditions a fold is fitted ``on`` take the times, make the queries and pick at the ranks the paper's participants
did in those conditions (Savva, Chang, Agrawala: SceneSuggest, Table 1 and Table 2; :mod:`.paper_tables`). A fold
fits the parameters its conditions can inform (those ``used`` in them, :func:`.human.free_parameters`); the others
keep their defaults. The conditions left out are predictions of the calibrated simulator: the fit asks the paper's
tables for its own conditions' cells only and never holds the held-out numbers (a test changes them and finds the
fit unchanged).

A *rehearsal* plays each bot's trials of the fold's conditions, at their place in its schedule row (the practice
effect), in process: the study's own scenes, model list, search index and engine answer, and the events the bot
would send are measured with the analysis' own definitions (:func:`analysis.measures.measures_by_trial`,
:func:`scenesuggest.contract.picks.picks`). The loss is the squared distance to the paper in units of its standard
errors (from the 95% intervals; rank shares in units of RANK_SE) plus a weak prior pulling each parameter to its
default. It is minimised by Nelder–Mead (scipy) over the parameters mapped to their ranges, with common random
numbers: every evaluation replays the same bots from the same seeds.

:func:`explain` measures what each condition can tell: how far each cell moves when each parameter moves.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import multiprocessing
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path, PurePosixPath
from urllib.parse import parse_qs, urlsplit

import numpy as np
import pandas as pd
from scipy.optimize import minimize

from scenesuggest.atomic import write_atomically
from scenesuggest.contract.events import SEND_BATCH
from scenesuggest.errors import SceneSuggestError
from scenesuggest.npz import read_npz

from . import paper_tables
from .human import Human, bounds, free_parameters, used_in
from .paper_tables import PARTICIPANTS, SPREAD_MEASURES, Cell
from .transport import Response

FORMAT = "scenesuggest-calibration"
VERSION = 2  # 2: fitted on named conditions ("on"), measured by condition
PRIOR_SD = 1.0  # the prior: each parameter's logit-scale distance from its default, in these units
#: The calibration's uncertainty: evaluated parameter sets whose loss is within this of the best (the loss is in
#: squared standard errors: 4 is two standard errors along one direction), at most PLAUSIBLE_SETS of them.
PLAUSIBLE_DELTA, PLAUSIBLE_SETS = 4.0, 5
SIMULATION_FILES = ("human.py", "actions.py", "timing.py", "participant.py")  # what the bots do


def priors_content_sha256(path: Path) -> str | None:
    """SHA-256 of what a priors file holds (its arrays, by name, and its metadata), leaving out the hash of the
    engine code that trained it: a change to the engine's code that leaves the learned numbers as they were
    (the priors file then differs in that hash only) keeps a calibration fresh."""
    if not path.is_file():
        return None
    h = hashlib.sha256()
    arrays = read_npz(path)
    for name in sorted(arrays):
        a = arrays[name]
        if name == "meta":
            meta = json.loads(a.tobytes())
            meta.pop("code", None)
            a = np.frombuffer(json.dumps(meta, sort_keys=True).encode(), dtype=np.uint8)
        h.update(f"{name}:{a.dtype.str}:{a.shape};".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def library_content_sha256(path: Path) -> str | None:
    """SHA-256 of what a model library's index holds (its models: names, tags, categories, sizes, …), leaving out
    where its source corpus and meshes lay on the machine that built it (a mesh counts by its file name) and the
    hash of the builders' code: the same library built from another checkout, or by code that builds the same
    models, keeps a calibration fresh."""
    if not path.is_file():
        return None
    index = json.loads(path.read_bytes())
    content = {k: v for k, v in index.items() if k not in ("source", "code")}
    # a model's source mesh is named by its file: the folder it lay in is that machine's
    content["models"] = [{**m, "mesh": PurePosixPath(str(m["mesh"]).replace("\\", "/")).name}
                         if isinstance(m, dict) and m.get("mesh") else m for m in content.get("models") or []]
    return hashlib.sha256(json.dumps(content, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def fingerprint(study) -> dict:
    """What a calibration depends on besides its parameters: the study, the content of its priors (the engine)
    and of its model library's index, and the simulation's code."""
    from scenesuggest.library.index import INDEX_FILE

    here = Path(__file__).parent
    code = hashlib.sha256(b"".join((here / name).read_bytes() for name in SIMULATION_FILES)).hexdigest()
    return {"study": study.id, "priors_content_sha256": priors_content_sha256(study.priors),
            "library_content_sha256": library_content_sha256(study.library / INDEX_FILE), "simulation_sha256": code}


@dataclass
class _Answer(Response):
    """An answer given in process, not encoded: what the bot reads is ``value`` itself (never shared: it is
    made for this request)."""

    value: object = None

    def json(self):
        return self.value


class _Local:
    """A transport that answers a bot's trial from the study's runtime in process (scenes, model list, search,
    suggestions, model files) and keeps the events it is sent instead of storing them. ``trial`` is the planned
    trial being played (its condition and scene answer a click for suggestions)."""

    def __init__(self, app, study_id: str):
        from study_server.trials.offline import OfflineAnswers

        self.answers = OfflineAnswers(app, study_id)
        self.client = app.test_client()
        self.cache: dict[str, Response] = {}
        self.events: list[dict] = []
        self.trial = None

    def _json(self, value) -> Response:
        return Response(200, json.dumps(value).encode())

    def get(self, path, headers=None) -> Response:
        if path not in self.cache:
            self.cache[path] = self._answer(path)
        return self.cache[path]

    def _answer(self, path: str) -> Response:
        url = urlsplit(path)
        if url.path.startswith("/api/scenes/"):
            which = parse_qs(url.query).get("which", ["target"])[0]
            return self._json(self.answers.scene(url.path.rsplit("/", 1)[1], which))
        if url.path == "/api/models":
            return self._json(self.answers.models())
        if url.path == "/api/search":
            return self._json(self.answers.search(parse_qs(url.query).get("q", [""])[0]))
        r = self.client.get(path)  # a model file
        return Response(r.status_code, r.get_data())

    def post(self, path, form=None, json_body=None, headers=None) -> Response:
        if path == "/api/events":
            self.events.extend({**e, "condition": self.trial.condition} for e in json_body["events"])
            return _Answer(200, b"", {"acked_seq": json_body["events"][-1]["seq"]})
        if path == "/api/suggest":
            return _Answer(200, b"", self.answers.suggest(self.trial.condition, self.trial.scene,
                                                          json_body["trial"], json_body))
        if path == "/api/trial/done":
            return self._json({})
        raise SceneSuggestError(f"a rehearsal does not send {path}")


#: The rehearsal a forked worker plays its share of the bots in (each worker adopts its pool's at its start).
_FORKED: Rehearsal | None = None


def _adopt(rehearsal: Rehearsal) -> None:
    global _FORKED
    _FORKED = rehearsal


def _play_share(human: Human, bots: range) -> list[dict]:
    return _FORKED.play(human, bots)


@dataclass
class Rehearsal:
    """The trials in ``conditions`` of ``participants`` bots (bot i: schedule row i, generator ``[seed, i]``;
    each trial its own generator ``[seed, i, position]``, so that a change in one trial leaves the others' draws
    as they were) of the study ``study_id`` served by ``app``. Trials of other conditions are not played.
    ``workers`` processes (forked from this one, the study loaded) share the bots; the events are the same
    for any number of them."""

    app: object
    study_id: str
    participants: int = 40
    seed: int = 0
    conditions: tuple[str, ...] = ("none",)
    workers: int = 1

    def __post_init__(self):
        self.local = _Local(self.app, self.study_id)
        self.study = self.local.answers.study
        self.symmetry: dict[str, float] = {}
        self.conditions = tuple(self.conditions)
        self._pool = None

    def play(self, human: Human, bots: range) -> list[dict]:
        """The events of bots ``bots`` behaving as ``human``, each with its participant and condition."""
        from .actions import BotTrial
        from .participant import Bot

        rows = []
        for i in bots:
            self.local.events = []
            bot = Bot(self.local, self.study_id, f"rehearsal-{i}", np.random.default_rng([self.seed, i]),
                      symmetry=self.symmetry, human=human, scene_seed=self.seed)
            for position, planned in enumerate(self.study.plan(i % self.study.n_rows)):
                if planned.kind != "trial" or planned.condition not in self.conditions:
                    continue
                bot.played, self.local.trial = position, planned
                bot.rng = np.random.default_rng([self.seed, i, position])
                boot = {"token": "", "page_id": "rehearsal", "vocabulary": 2, "batch": SEND_BATCH,
                        "trial": {"index": planned.index, "kind": "trial", "condition": planned.condition,
                                  "scene": planned.scene}}
                BotTrial(bot, boot).play()
            rows.extend({**e, "participant": i} for e in self.local.events)
        return rows

    def events(self, human: Human) -> pd.DataFrame:
        """Every event the bots' trials would send, with columns participant, condition, trial, seq, type,
        client_t_ms and payload."""
        if self.workers <= 1:
            rows = self.play(human, range(self.participants))
        else:
            if self._pool is None:
                sql = getattr(self.app, "extensions", {}).get("sqlalchemy")
                if sql is not None:  # no database connection crosses the fork
                    with self.app.app_context():
                        sql.engine.dispose()
                self._pool = multiprocessing.get_context("fork").Pool(self.workers, initializer=_adopt,
                                                                      initargs=(self,))
            shares = np.array_split(np.arange(self.participants), self.workers)
            rows = [row for part in self._pool.starmap(_play_share, [(human, range(int(s[0]), int(s[-1]) + 1))
                                                                      for s in shares if len(s)])
                    for row in part]
        return pd.DataFrame(rows).rename(columns={"t": "client_t_ms"})

    def measure(self, human: Human) -> dict[str, dict[str, float]]:
        """The paper's measures of the bots behaving as ``human``, by condition (:func:`measure`)."""
        events = self.events(human)
        return {c: measure(events[events["condition"] == c]) for c in self.conditions}

    def close(self) -> None:
        """Stop the worker processes (if any)."""
        if self._pool is not None:
            self._pool.terminate()
            self._pool.join()
            self._pool = None

    def __enter__(self) -> Rehearsal:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def measure(events: pd.DataFrame) -> dict[str, float]:
    """The paper's measures of one condition's events, by the analysis' definitions: per-trial means of total,
    rotation and translation time (seconds) and keyword queries; MRR and rank shares over final picks; and for each
    time the standard error of its mean over PARTICIPANTS people (``total_time_se``, …, seconds: the spread of
    people's means)."""
    from analysis.measures import measures_by_trial
    from scenesuggest.contract.picks import picks

    events = events.sort_values(["participant", "trial", "seq"], kind="stable")
    keys = pd.MultiIndex.from_arrays([events["participant"], events["trial"]])
    unique = keys.unique()
    per_trial = measures_by_trial(events, unique.get_indexer(keys), len(unique))
    ranks = []
    for _, own in events.sort_values(["participant", "seq"]).groupby("participant", sort=False):
        ranks += [p.rank for p in picks(own.rename(columns={"client_t_ms": "t"}).to_dict("records"))
                  if p.final and p.rank]
    ranks = np.asarray(ranks, dtype=float)
    out = {name: float(np.nanmean(per_trial[name])) for name in ("total_time", "rotation_time",
                                                                  "translation_time", "n_text_queries")}
    people = unique.get_level_values(0)
    for name in SPREAD_MEASURES:  # the standard error of the mean over the paper's number of people
        per_person = pd.Series(per_trial[name]).groupby(np.asarray(people)).mean()
        out[f"{name}_se"] = float(per_person.std(ddof=1) / math.sqrt(PARTICIPANTS)) if len(per_person) > 1 \
            else float("nan")
    out["mrr"] = float(np.mean(1.0 / ranks)) if len(ranks) else float("nan")
    for label, hit in (("1", ranks == 1), ("2", ranks == 2), ("3", ranks == 3), ("4+", ranks >= 4)):
        out[f"rank_{label}"] = float(hit.mean()) if len(ranks) else float("nan")
    return out


def _to_unit(name: str, value: float) -> float:
    low, high = bounds(name)
    x = min(max((value - low) / (high - low), 1e-6), 1 - 1e-6)
    return math.log(x / (1 - x))


def _from_unit(name: str, u: float) -> float:
    low, high = bounds(name)
    return low + (high - low) / (1 + math.exp(-u))


def loss(measured: dict[str, dict[str, float]], cells: tuple[Cell, ...], u: np.ndarray | None = None,
         u0: np.ndarray | None = None) -> float:
    """Squared distance of ``measured`` (condition → measure → value) to the paper's ``cells`` in their standard
    errors, plus the prior on the parameters' logits ``u`` (distance from the defaults ``u0``)."""
    total = sum(((measured[c.condition][c.measure] - c.mean) / c.se) ** 2 for c in cells)
    if u is not None:
        total += float(np.sum(((u - u0) / PRIOR_SD) ** 2))
    return total if math.isfinite(total) else 1e9


def fit(rehearsal: Rehearsal, evaluations: int = 300, start: Human | None = None,
        progress=lambda message: None, draws: int = 0, draw_evaluations: int = 100, seed: int = 0) -> dict:
    """Fit the parameters the rehearsal's conditions inform to the paper's cells of those conditions
    (Nelder–Mead, at most ``evaluations`` rehearsals); returns the calibration document (see :func:`write`),
    with ``draws`` refits for its uncertainty (:func:`add_draws`)."""
    on = paper_tables.conditions_of(rehearsal.conditions)
    document = _fit(rehearsal, paper_tables.cells(on), evaluations, start, progress)
    return add_draws(rehearsal, document, draws, draw_evaluations, seed, progress) if draws else document


def add_draws(rehearsal: Rehearsal, document: dict, draws: int, evaluations: int = 100, seed: int = 0,
              progress=lambda message: None) -> dict:
    """The calibration ``document`` with its uncertainty as ``draws`` refits (``evaluations`` each, from its best
    fit) on its cells drawn from their sampling distributions (:func:`drawn_cells`, generator ``[seed, k]``);
    the draws it has already are kept."""
    on = paper_tables.conditions_of(rehearsal.conditions)
    if document.get("on") != list(on):
        raise SceneSuggestError(f"a calibration fitted on {_fold(document.get('on'))} cannot be refitted on "
                                f"{_fold(on)}", field="on")
    cells, best = paper_tables.cells(on), Human().with_values(document["parameters"])
    done = list(document.get("draws") or [])
    started = time.perf_counter()
    for k in range(len(done), draws):
        drawn = drawn_cells(cells, np.random.default_rng([seed, k]))
        refit = _fit(rehearsal, drawn, evaluations, best,
                     lambda message, k=k: progress(f"draw {k + 1}/{draws}: {message}"))
        done.append({"cells": {c.key: c.mean for c in drawn}, "loss": refit["loss"],
                     "parameters": refit["parameters"], "evaluations": refit["evaluations"],
                     "seconds": round(time.perf_counter() - started, 1)})
    return {**document, "draws": done, "draws_seed": seed}


def drawn_cells(cells: tuple[Cell, ...], rng: np.random.Generator) -> tuple[Cell, ...]:
    """``cells`` as another study of the paper's size might have found them: each mean normal about the paper's
    with its standard error, each share with RANK_SE (within [0, 1]), each spread with its own (above 0); the
    standard errors a fit weighs them by stay the paper's."""
    out = []
    for c in cells:
        value = c.mean + c.se * float(rng.normal())
        value = min(max(value, 0.0), 1.0) if c.kind == "share" else max(value, 0.05 * c.mean)
        out.append(dataclasses.replace(c, mean=value, fixed_se=c.se))
    return tuple(out)


def _fit(rehearsal: Rehearsal, cells: tuple[Cell, ...], evaluations: int, start: Human | None,
         progress) -> dict:
    on = paper_tables.conditions_of(rehearsal.conditions)
    names = free_parameters(on)
    # only the parameters this fold fits come from a start; every other keeps its default
    start = Human().with_values({n: getattr(start, n) for n in names}) if start else Human()
    u0 = np.array([_to_unit(n, getattr(Human(), n)) for n in names])
    u_start = np.array([_to_unit(n, getattr(start, n)) for n in names])
    seen: dict[tuple, tuple[float, dict]] = {}
    started = time.perf_counter()

    def human_of(u) -> Human:
        return start.with_values({n: _from_unit(n, float(x)) for n, x in zip(names, u, strict=True)})

    def objective(u) -> float:
        key = tuple(np.round(u, 10))
        if key not in seen:
            measured = rehearsal.measure(human_of(u))
            seen[key] = (loss(measured, cells, u, u0), measured)
            best = min(v[0] for v in seen.values())
            progress(f"evaluation {len(seen)}: loss {seen[key][0]:.2f} (best {best:.2f}), "
                     f"{time.perf_counter() - started:.0f} s")
        return seen[key][0]

    result = minimize(objective, u_start, method="Nelder-Mead",
                      options={"maxfev": evaluations, "xatol": 1e-3, "fatol": 1e-3, "initial_simplex":
                               u_start + np.vstack([np.zeros(len(names)), 0.7 * np.eye(len(names))])})
    best_u = min(seen, key=lambda k: seen[k][0])
    human = human_of(np.asarray(best_u))
    value, measured = seen[best_u]
    plausible = _plausible(seen, best_u, value)
    return {"format": FORMAT, "version": VERSION, "fingerprint": fingerprint(rehearsal.study),
            "on": list(on), "held_out": list(paper_tables.held_out(on)),
            "parameters": human.values(), "free": names, "loss": value,
            "loss_without_prior": loss(measured, cells), "measured": measured,
            "plausible": [{"loss": seen[u][0], "parameters": human_of(np.asarray(u)).values()} for u in plausible],
            "paper": {c.key: [c.mean, c.low, c.high] for c in cells},
            "seed": rehearsal.seed, "participants": rehearsal.participants, "evaluations": len(seen),
            "converged": bool(result.success), "seconds": round(time.perf_counter() - started, 1),
            "created": datetime.now(UTC).isoformat(timespec="seconds")}


#: A parameter informs a condition when a one-logit move of it moves one of the condition's cells by at least
#: this many of the cell's standard errors.
INFORMS_SE = 0.5


def explain(rehearsal: Rehearsal, base: Human | None = None, step: float = 0.5,
            progress=lambda message: None) -> dict:
    """What each condition can tell of each free parameter: every cell's change per logit unit of the
    parameter (a central difference of ``step`` logits about ``base``, common random numbers), in the cell's
    standard errors, for the rehearsal's conditions; a parameter informs a condition when some cell of it moves by
    INFORMS_SE or more. Parameters a condition does not use move none of its cells (exactly: their trials do not
    read them)."""
    base = base or Human()
    cells = paper_tables.cells(rehearsal.conditions)
    rows, started = [], time.perf_counter()
    for name in free_parameters(rehearsal.conditions):
        u = _to_unit(name, getattr(base, name))
        up, down = (rehearsal.measure(base.with_values({name: _from_unit(name, u + d)})) for d in (step, -step))
        effects = {c.key: (up[c.condition][c.measure] - down[c.condition][c.measure]) / (2 * step) / c.se
                   for c in cells}
        effects = {k: (v if math.isfinite(v) else 0.0) for k, v in effects.items()}
        informs = [c for c in rehearsal.conditions
                   if max(abs(v) for k, v in effects.items() if k.startswith(f"{c}.")) >= INFORMS_SE]
        rows.append({"parameter": name, "value": getattr(base, name), "used": list(used_in(name)),
                     "effects": effects, "informs": informs})
        progress(f"{name}: informs {', '.join(informs) or 'no condition'} "
                 f"({time.perf_counter() - started:.0f} s)")
    return {"conditions": list(rehearsal.conditions), "step_logit": step, "informs_se": INFORMS_SE,
            "base": base.values(), "participants": rehearsal.participants, "seed": rehearsal.seed,
            "parameters": rows, "seconds": round(time.perf_counter() - started, 1)}


def explain_lines(table: dict) -> list[str]:
    """The identifiability table as Markdown: one row per parameter, one column per condition (the largest cell
    movement, in standard errors per logit, and the cell that moves most)."""
    conditions = table["conditions"]
    lines = [f"| Parameter | used in | {' | '.join(conditions)} | informed by |",
             f"|---|---|{'---:|' * len(conditions)}---|"]
    for row in table["parameters"]:
        cols = []
        for c in conditions:
            own = {k.split(".", 1)[1]: v for k, v in row["effects"].items() if k.startswith(f"{c}.")}
            top = max(own, key=lambda k: abs(own[k]))
            cols.append(f"{abs(own[top]):.2f} ({top})" if abs(own[top]) > 0 else "0")
        lines.append(f"| `{row['parameter']}` | {', '.join(row['used'])} | {' | '.join(cols)} | "
                     f"{', '.join(f'`{c}`' for c in row['informs']) or 'no condition'} |")
    return lines


def _plausible(seen: dict, best: tuple, value: float, count: int = PLAUSIBLE_SETS) -> list[tuple]:
    """The calibration's uncertainty as parameter sets: the best one, then evaluated sets whose loss is within
    PLAUSIBLE_DELTA of it, each chosen farthest (in logits) from those already chosen."""
    near = [u for u, (v, _) in seen.items() if v <= value + PLAUSIBLE_DELTA and u != best]
    chosen = [best]
    while near and len(chosen) < count:
        far = max(near, key=lambda u: min(float(np.linalg.norm(np.subtract(u, c))) for c in chosen))
        chosen.append(far)
        near.remove(far)
    return chosen


def write(document: dict, path: Path) -> None:
    write_atomically(Path(path), (json.dumps(document, indent=1, sort_keys=True) + "\n").encode())


def read_plausible(path: Path, study=None, on: tuple[str, ...] | None = None) -> list[Human]:
    """The calibration's plausible parameter sets, the best first: its refits on drawn cells when it has them
    (``study calibrate --draws``), else the evaluated sets that fit almost as well (:func:`_plausible`)."""
    best = read(path, study, on)
    document = json.loads(Path(path).read_text())
    key = "draws" if document.get("draws") else "plausible"
    entries = document.get(key) or []
    out = [best]
    for k, entry in enumerate(entries[1:] if key == "plausible" else entries, start=1 if key == "plausible" else 0):
        try:
            out.append(Human().with_values(entry["parameters"]))
        except (SceneSuggestError, KeyError, TypeError, AttributeError) as e:
            raise SceneSuggestError(f"{e}", file=str(path), field=f"{key}[{k}]") from None
    return out


def read(path: Path, study=None, on: tuple[str, ...] | None = None) -> Human:
    """The calibrated :class:`Human` of the calibration file ``path``; with ``study``, the file must have been
    fitted on that study, its priors, its model library and this simulation code, and with ``on``, on those
    conditions (errors name what differs)."""
    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except FileNotFoundError:
        raise SceneSuggestError("no such calibration file (make one with `study calibrate`)",
                                file=str(path)) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise SceneSuggestError(f"not a calibration file ({e})", file=str(path)) from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise SceneSuggestError(f"not a calibration file (format is not {FORMAT!r})", file=str(path))
    if document.get("version") != VERSION:
        raise SceneSuggestError(f"calibration version {document.get('version')!r}, expected {VERSION}",
                                file=str(path), field="version")
    fitted = fitted_on(document)
    if fitted is None:
        raise SceneSuggestError(f"not a fold of the paper's conditions: {document.get('on')!r}", file=str(path),
                                field="on")
    if on is not None and fitted != tuple(on):
        raise SceneSuggestError(f"fitted on {_fold(fitted)}, not on {_fold(on)}", file=str(path), field="on")
    if study is not None:
        stale = stale_keys(document, study)
        if stale:
            raise SceneSuggestError(f"fitted with another {', '.join(stale)} than this study's; calibrate again",
                                    file=str(path), field="fingerprint")
    values = document.get("parameters")
    if not isinstance(values, dict):
        raise SceneSuggestError("no parameters", file=str(path), field="parameters")
    try:
        return Human().with_values(values)
    except SceneSuggestError as e:
        raise SceneSuggestError(e.message, file=str(path), field=f"parameters.{e.field}") from None


def _fold(on) -> str:
    return " + ".join(on) if isinstance(on, list | tuple) and on else repr(on)


def fitted_on(document: dict) -> tuple[str, ...] | None:
    """The conditions a calibration ``document`` was fitted on, or None when its ``on`` names no fold (one or two
    of the paper's conditions, in their order)."""
    on = document.get("on")
    if not isinstance(on, list) or not all(isinstance(c, str) for c in on):
        return None
    try:
        fold = paper_tables.conditions_of(on)
    except SceneSuggestError:
        return None
    return fold if list(fold) == on else None


def stale_keys(document: dict, study, on: tuple[str, ...] | None = None) -> list[str]:
    """What the calibration ``document`` was fitted with that differs from ``study`` now (any of study, priors,
    library, simulation), from the paper's cells of its conditions (as :mod:`.paper_tables` holds them now) and,
    given ``on``, from those conditions; an older format is stale too."""
    if document.get("format") != FORMAT or document.get("version") != VERSION:
        return ["format"]
    fitted = fitted_on(document)
    if fitted is None or (on is not None and fitted != tuple(on)):
        return ["conditions"]
    targets = {c.key: [c.mean, c.low, c.high] for c in paper_tables.cells(fitted)}
    if document.get("paper") != targets:
        return ["paper's numbers"]
    now, then = fingerprint(study), document.get("fingerprint") or {}
    names = {"study": "study", "priors_content_sha256": "priors (the engine)",
             "library_content_sha256": "model library", "simulation_sha256": "simulation code"}
    return [label for key, label in names.items() if then.get(key) != now[key]]
