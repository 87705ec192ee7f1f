"""Calibrating the simulated participants on the paper's ``none`` condition, and only on it.

The free parameters of :class:`~.human.Human` are fitted so that bots rebuilding the study's targets with the
model list and keyword search (``none``) take the times, make the queries and pick at the ranks the paper's
participants did in ``none`` (Savva, Chang, Agrawala: SceneSuggest, Table 1 and Table 2). The suggestion
conditions are then predictions of the calibrated simulator: nothing here knows their numbers (a test reads this
file's source to hold it so).

A *rehearsal* plays each bot's ``none`` trials of its schedule row, at their place in the row (the practice
effect), in process: the study's own scenes, model list and search index answer, and the events the bot would
send are measured with the analysis' own definitions (:func:`analysis.measures.measures_by_trial`,
:func:`scenesuggest.contract.picks.picks`). The loss is the squared distance to the paper in units of its standard
errors (from the 95% intervals; rank shares in units of RANK_SE) plus a weak prior pulling each parameter to its
default. It is minimised by Nelder–Mead (scipy) over the parameters mapped to their ranges, with common random
numbers: every evaluation replays the same bots from the same seeds.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

import numpy as np
import pandas as pd
from scipy.optimize import minimize

from scenesuggest.atomic import write_atomically
from scenesuggest.contract.events import SEND_BATCH
from scenesuggest.errors import SceneSuggestError
from scenesuggest.npz import read_npz

from .human import Human, bounds, free_parameters
from .transport import Response

FORMAT = "scenesuggest-calibration"
VERSION = 1
#: The paper's ``none`` condition: Table 1 means with their 95% bootstrap intervals (seconds, queries, MRR)
#: and Table 2 rank shares (picks at rank 1, 2, 3, 4 or lower).
PAPER_NONE = {
    "total_time": (204.0, 177.0, 241.0),
    "rotation_time": (23.6, 19.9, 28.7),
    "translation_time": (40.5, 32.0, 51.1),
    "n_text_queries": (5.2, 3.8, 7.0),
    "mrr": (0.353, 0.318, 0.388),
}
PAPER_NONE_RANKS = {"1": 0.296, "2": 0.140, "3": 0.0035, "4+": 0.560}
RANK_SE = 0.05  # the paper gives no interval for rank shares: a share off by 5 points costs one standard error
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


def fingerprint(study) -> dict:
    """What a calibration depends on besides its parameters: the study, the content of its priors (the engine)
    and its model library's index (SHA-256 of the file), and the simulation's code."""
    from scenesuggest.library.index import INDEX_FILE

    def sha256(path: Path) -> str | None:
        return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None

    here = Path(__file__).parent
    code = hashlib.sha256(b"".join((here / name).read_bytes() for name in SIMULATION_FILES)).hexdigest()
    return {"study": study.id, "priors_content_sha256": priors_content_sha256(study.priors),
            "library_sha256": sha256(study.library / INDEX_FILE), "simulation_sha256": code}


class _Local:
    """A transport that answers a bot's ``none`` trial from the study's runtime in process (scenes, model list,
    search, model files) and keeps the events it is sent instead of storing them."""

    def __init__(self, app, study_id: str):
        from study_server.studies.offline import OfflineAnswers

        self.answers = OfflineAnswers(app, study_id)
        self.client = app.test_client()
        self.cache: dict[str, Response] = {}
        self.events: list[dict] = []

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
            self.events.extend(json_body["events"])
            return self._json({"acked_seq": json_body["events"][-1]["seq"]})
        if path == "/api/trial/done":
            return self._json({})
        raise SceneSuggestError(f"a rehearsal does not send {path}")


@dataclass
class Rehearsal:
    """The ``none`` trials of ``participants`` bots (bot i: schedule row i, generator ``[seed, i]``) of the study
    ``study_id`` served by ``app``."""

    app: object
    study_id: str
    participants: int = 40
    seed: int = 0

    def __post_init__(self):
        self.local = _Local(self.app, self.study_id)
        self.study = self.local.answers.study
        self.symmetry: dict[str, float] = {}

    def events(self, human: Human) -> pd.DataFrame:
        """Every event the bots' ``none`` trials would send, with columns participant, trial, seq, type,
        client_t_ms and payload."""
        from .actions import BotTrial
        from .participant import Bot

        rows = []
        for i in range(self.participants):
            self.local.events = []
            bot = Bot(self.local, self.study_id, f"rehearsal-{i}", np.random.default_rng([self.seed, i]),
                      symmetry=self.symmetry, human=human, scene_seed=self.seed)
            for position, planned in enumerate(self.study.plan(i % self.study.n_rows)):
                if planned.kind != "trial" or planned.condition != "none":
                    continue
                bot.played = position
                boot = {"token": "", "page_id": "rehearsal", "vocabulary": 2, "batch": SEND_BATCH,
                        "trial": {"index": planned.index, "kind": "trial", "condition": "none",
                                  "scene": planned.scene}}
                BotTrial(bot, boot).play()
            rows.extend({**e, "participant": i} for e in self.local.events)
        frame = pd.DataFrame(rows)
        return frame.rename(columns={"t": "client_t_ms"})


def measure(events: pd.DataFrame) -> dict[str, float]:
    """The paper's ``none`` measures of a rehearsal's events, by the analysis' definitions: per-trial means of
    total, rotation and translation time and keyword queries; MRR and rank shares over final picks."""
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


def loss(measured: dict[str, float], u: np.ndarray | None = None, u0: np.ndarray | None = None) -> float:
    """Squared distance of ``measured`` to the paper's ``none`` row in standard errors, plus the prior on the
    parameters' logits ``u`` (distance from the defaults ``u0``)."""
    total = 0.0
    for name, (mean, low, high) in PAPER_NONE.items():
        se = (high - low) / (2 * 1.96)
        total += ((measured[name] - mean) / se) ** 2
    for label, share in PAPER_NONE_RANKS.items():
        total += ((measured[f"rank_{label}"] - share) / RANK_SE) ** 2
    if u is not None:
        total += float(np.sum(((u - u0) / PRIOR_SD) ** 2))
    return total if math.isfinite(total) else 1e9


def fit(rehearsal: Rehearsal, evaluations: int = 300, start: Human | None = None,
        progress=lambda message: None) -> dict:
    """Fit the free parameters (Nelder–Mead, at most ``evaluations`` rehearsals); returns the calibration
    document (see :func:`write`)."""
    names = free_parameters()
    start = start or Human()
    u0 = np.array([_to_unit(n, getattr(Human(), n)) for n in names])
    u_start = np.array([_to_unit(n, getattr(start, n)) for n in names])
    seen: dict[tuple, tuple[float, dict]] = {}
    started = time.perf_counter()

    def human_of(u) -> Human:
        return start.with_values({n: _from_unit(n, float(x)) for n, x in zip(names, u, strict=True)})

    def objective(u) -> float:
        key = tuple(np.round(u, 10))
        if key not in seen:
            measured = measure(rehearsal.events(human_of(u)))
            seen[key] = (loss(measured, u, u0), measured)
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
            "parameters": human.values(), "free": names, "loss": value,
            "loss_without_prior": loss(measured), "measured_none": measured,
            "plausible": [{"loss": seen[u][0], "parameters": human_of(np.asarray(u)).values()} for u in plausible],
            "paper_none": {**PAPER_NONE, **{f"rank_{k}": v for k, v in PAPER_NONE_RANKS.items()}},
            "seed": rehearsal.seed, "participants": rehearsal.participants, "evaluations": len(seen),
            "converged": bool(result.success), "seconds": round(time.perf_counter() - started, 1),
            "created": datetime.now(UTC).isoformat(timespec="seconds")}


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


def read_plausible(path: Path, study=None) -> list[Human]:
    """The calibration's plausible parameter sets (the best first; see :func:`_plausible`)."""
    best = read(path, study)
    document = json.loads(Path(path).read_text())
    out = [best]
    for k, entry in enumerate(document.get("plausible", [])[1:], start=1):
        try:
            out.append(Human().with_values(entry["parameters"]))
        except (SceneSuggestError, KeyError, TypeError) as e:
            raise SceneSuggestError(f"{e}", file=str(path), field=f"plausible[{k}]") from None
    return out


def read(path: Path, study=None) -> Human:
    """The calibrated :class:`Human` of the calibration file ``path``; with ``study``, the file must have been
    fitted on that study, its priors, its model library and this simulation code (errors name what differs)."""
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


def stale_keys(document: dict, study) -> list[str]:
    """What the calibration ``document`` was fitted with that differs from ``study`` now: any of study, priors,
    library, simulation."""
    now, then = fingerprint(study), document.get("fingerprint") or {}
    names = {"study": "study", "priors_content_sha256": "priors (the engine)", "library_sha256": "model library",
             "simulation_sha256": "simulation code"}
    return [label for key, label in names.items() if then.get(key) != now[key]]
