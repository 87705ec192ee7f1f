"""Offline evaluation: k-fold by scene, one query per held-out support edge.

For every object of a held-out scene that rests on a parent, the object is removed (with everything it
supports), the engine is asked at its true contact point on its true parent with the true normal, in a room whose
type does not come from the object (:mod:`scenesuggest.suggestion.held_out`), and the rank of its true category
among those that may be suggested is recorded (:mod:`scenesuggest.suggestion.suggestable`: an object of a
placeholder category, Unknown, is no query). Edges whose contact lies far from the parent's box are bad data,
skipped and counted. A category never seen in training has no rank (reciprocal rank 0). Ties count half:
rank = 1 + (#scored higher) + (#scored equal)/2.

Folds keep near-copies of a scene together (:mod:`scenesuggest.corpora.folds`; ``group_similar``, the default); the
figures of plain k-fold by scene are reported beside them under ``"ungrouped"``.

Orientation: the true category is also placed, in ``full`` mode and in the canonical pose that ``basic`` uses
(the geometric attachment face, no turn). Reported for each (:func:`orientation_summary`): the fractions within
15° and 45° of the angle between the predicted and the true front (``orient_within_*``, the unfolded figure),
the same for the rotation error folded by the model's rotational symmetry about its up axis
(``orient_folded_within_*``, :func:`~scenesuggest.contract.pose_error.pose_error_deg`; periods from meshes, see
:mod:`scenesuggest.assets.symmetry`) and the median folded error. Per category under ``"categories"``; chairs standing
beside a table or desk under ``"chairs_at_tables"`` (also: how often the suggested chair faces the nearest one).

Baselines rank by: global category frequency (``frequency``); P(|C on p| > k) alone (``parent_only``); the
full score without back-off (``no_backoff``); the score without the position term (``no_position``).
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from ..assets.symmetry import ModelPeriods, corpus_periods
from ..contract.pose_error import front_angle_deg, pose_error_deg
from ..corpora.corpus import Corpus
from ..corpora.folds import folds_of, grouped_folds, similar_groups
from ..engines import EngineSpec
from ..errors import SceneSuggestError
from ..learning.priors import Priors
from ..scenes import poses
from ..scenes.scene import ObjectInstance, Scene
from ..scenes.surfaces import attachment_face
from ..suggestion.held_out import DEFAULT_SCENE_TYPE, check_scene_type, held_out_queries
from ..suggestion.suggest import ContextQuery, Engine, EngineOptions
from ..suggestion.suggestable import suggestable

BASELINES = ("frequency", "parent_only", "no_backoff", "no_position")
#: Orientation ablations (``evaluate(..., ablations=True)``): name → Priors.fit options. Each is trained and
#: measured on the same folds; the paper's rule and the canonical pose are measured in every run.
ABLATIONS = {
    "all evidence, learned trust": {},
    "without walls": {"orientation_kinds": ("canonical", "parent_front", "parent_bearing", "sibling_front",
                                            "sibling_bearing")},
    "without bearings": {"orientation_kinds": ("canonical", "parent_front", "sibling_front", "wall")},
    "without the canonical prior": {"orientation_kinds": ("parent_front", "parent_bearing", "sibling_front",
                                                          "sibling_bearing", "wall")},
    "fronts only (the paper's evidence)": {"orientation_kinds": ("parent_front", "sibling_front")},
    "all evidence, equal trust": {"orientation_trust": "equal"},
}
#: Poses whose orientation is measured: the engine's full mode, full mode with the paper's orientation rule, the
#: learned engine's frame classifier's choice, and the canonical pose of basic mode.
POSES = ("full", "paper", "frames", "canonical")
TOLERANCES_DEG = (15, 45)

__all__ = ["evaluate", "folds_of", "rank_of", "summary", "orientation_summary", "paired_difference", "run_folds",
           "measure_query", "fitted_engine", "engine_figures", "ranks_by_category", "check_evaluable", "checked_specs"]


def rank_of(scores: np.ndarray, index: int | None, among: np.ndarray | None = None) -> float:
    """1-based rank of ``index`` in ``scores`` (higher is better; ties count half) among the candidates ``among``
    (a bool mask; default: all); inf when absent."""
    if index is None:
        return math.inf
    if among is not None:
        if not among[index]:
            return math.inf
        scores = np.where(among, scores, -np.inf)
    s = scores[index]
    return 1.0 + float((scores > s).sum()) + float((scores == s).sum() - 1) / 2.0


def summary(ranks: list[float]) -> dict:
    r = np.array(ranks, dtype=float)
    if not len(r):
        return {"mrr": 0.0, "top1": 0.0, "top5": 0.0, "n": 0}
    return {"mrr": float(np.mean(1.0 / r)), "top1": float(np.mean(r <= 1)), "top5": float(np.mean(r <= 5)),
            "n": int(len(r))}


def orientation_summary(front: list[float], folded: list[float]) -> dict:
    """Fractions (0..1) within 15° and 45°, unfolded (angle between fronts) and folded by symmetry, and the
    median folded error in degrees."""
    f, g = np.asarray(front, dtype=float), np.asarray(folded, dtype=float)
    out = {}
    for tol in TOLERANCES_DEG:
        out[f"orient_within_{tol}"] = float(np.mean(f <= tol)) if len(f) else 0.0
    for tol in TOLERANCES_DEG:
        out[f"orient_folded_within_{tol}"] = float(np.mean(g <= tol)) if len(g) else 0.0
    out["orient_median_deg"] = float(np.median(g)) if len(g) else 0.0
    out["orient_n"] = int(len(g))
    return out


def _is_chair(category: str, corpus: Corpus) -> bool:
    return any(c.endswith("Chair") for c in [category, *corpus.taxonomy.ancestors(category)])


def _is_table(category: str, corpus: Corpus) -> bool:
    return any(c in ("Table", "Desk") for c in [category, *corpus.taxonomy.ancestors(category)])


def _nearest_table(scene: Scene, o: ObjectInstance, corpus: Corpus) -> ObjectInstance | None:
    """For a chair: the table or desk on the same parent whose centre is nearest (None if there is none)."""
    if not _is_chair(o.category, corpus):
        return None
    tables = [q for q in scene.children(o.parent) if q.id != o.id and _is_table(q.category, corpus)]
    if not tables:
        return None
    return min(tables, key=lambda q: float(np.linalg.norm((q.centre() - o.centre())[[0, 2]])))


def _facing_error_deg(placement: np.ndarray, size, target: ObjectInstance, normal) -> float:
    """Angle (degrees) between a placed object's front and the direction from it to ``target``'s centre, both
    in the support plane."""
    position = poses.rotation_of(placement) @ (np.asarray(size, dtype=float) * [0, 0.5, 0]) + placement[:3, 3]
    front = poses.heading(poses.rotation_of(placement)[:, 2], normal)
    towards = poses.heading(target.centre() - position, normal)
    if math.isnan(front) or math.isnan(towards):
        return 180.0
    return abs(math.degrees(float(poses.wrap(front - towards + math.pi)) - math.pi))


#: The suggestions a query's timing asks for (what the study server shows).
TIMED_TOP = 40


@dataclass
class EngineRun:
    """One engine's answers on the held-out queries: a rank per query (aligned across engines), one
    orientation record per query whose category it knows, and the time of each suggestion request (seconds)."""

    ranks: list[float] = field(default_factory=list)
    records: list[dict] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)


@dataclass
class Run:
    """Ranks of the baselines (from the fold's paper priors), each engine's run, the scene group of every query
    (for the paired bootstrap) and the number of skipped edges."""

    baselines: dict[str, list[float]]
    engines: dict[str, EngineRun]
    groups: list[int] = field(default_factory=list)
    categories: list[str] = field(default_factory=list)
    skipped: int = 0


def check_evaluable(specs: list[EngineSpec]) -> None:
    """Every engine must be one the project can train per fold (or answers from the fold's priors)."""
    for spec in specs:
        if not (spec.kind.trainable or hasattr(spec.kind, "from_priors")):
            raise SceneSuggestError(f"the {spec.name!r} engine is not trained by this project, so it cannot be "
                                    "evaluated on held-out folds", field="engine")


def checked_specs(engines: list[EngineSpec] | None, options: EngineOptions) -> list[EngineSpec]:
    """The engines to evaluate (default: the paper's with ``options``), each named once, each one this project
    trains (:func:`check_evaluable`)."""
    specs = list(engines or [EngineSpec("paper", {"name": "paper"}, options)])
    if len({s.name for s in specs}) != len(specs):
        raise SceneSuggestError("each engine may be named once", field="engine")
    check_evaluable(specs)
    return specs


def fitted_engine(spec: EngineSpec, priors: Priors, train: list[Scene], corpus: Corpus, seed: int,
            periods: ModelPeriods, progress):
    """The engine of ``spec`` trained on one fold: from the fold's priors where the kind answers from them."""
    kind = spec.kind
    if hasattr(kind, "from_priors"):
        return kind.from_priors(spec.config, priors)
    return kind.fit(spec.config, train, corpus.taxonomy, seed=seed, periods=periods, progress=progress)


def _rank_and_poses(engine, query: ContextQuery, category: str):
    """(rank of ``category``, its full-mode and basic-mode placements or None, the engine's scores or None)
    for an engine that scores every candidate, else from its answers (the protocol only)."""
    if hasattr(engine, "score") and hasattr(engine, "choose_poses"):
        scores = engine.score(query, engine.suggestable)  # (the learned engine shortlists as it suggests)
        index = engine.index.get(category)
        if index is None:
            return math.inf, None, None, scores
        prep = scores.prepared
        placed = []
        for mode in ("full", "basic"):
            faces, alphas, _ = engine.choose_poses(scores, mode, [index])
            placed.append(poses.placement(prep.point, prep.normal, faces[0], engine.size[index], float(alphas[0])))
        return rank_of(scores.total, index, engine.suggestable), placed[0], placed[1], scores
    ranked = [s.category for s in engine.suggest(query, "basic") if suggestable(s.category)]
    rank = ranked.index(category) + 1.0 if category in ranked else math.inf
    placed = [engine.suggest(query, mode, top=1, only=[category]) for mode in ("full", "basic")]
    if not placed[0]:
        return rank, None, None, None
    return rank, placed[0][0].placement, placed[1][0].placement, None


def run_folds(corpus: Corpus, folds: list[np.ndarray], options: EngineOptions, periods: ModelPeriods,
              progress, fit_options: dict | None = None, rankings: bool = True,
              specs: list[EngineSpec] | None = None, groups: list[int] | None = None, seed: int = 0,
              scene_type: str = DEFAULT_SCENE_TYPE) -> Run:
    """Every engine of ``specs`` (default: the paper's with ``options``) and the baselines on the held-out
    queries of ``folds`` (``rankings=False``: the baselines are not ranked, for orientation-only runs), each with
    the room's type as ``scene_type`` says (:mod:`scenesuggest.suggestion.held_out`). Ranks are among the
    categories that may be suggested (no placeholder)."""
    specs = specs or [EngineSpec("paper", {"name": "paper"}, options)]
    run = Run({b: [] for b in BASELINES}, {s.name: EngineRun() for s in specs})
    for held in progress(folds, "folds"):
        held_set = set(held.tolist())
        train = [s for i, s in enumerate(corpus.scenes) if i not in held_set]
        priors = Priors.fit(train, corpus.taxonomy, **(fit_options or {}))
        paper = Engine(priors, options)
        plain, paper_rule = paper.with_options(backoff=False), paper.with_options(orientation="paper")
        engines = {s.name: paper if s.name == "paper" and s.config == options else
                   fitted_engine(s, priors, train, corpus, seed, periods, progress) for s in specs}
        for i in held:
            scene = corpus.scenes[i]
            for query, o in held_out_queries(scene, corpus.taxonomy, scene_type):
                try:
                    scores = paper.score(query)
                except SceneSuggestError:  # a contact far from its parent's box: bad data, not a query
                    run.skipped += 1
                    continue
                run.groups.append(groups[i] if groups is not None else int(i))
                run.categories.append(o.category)
                index = paper.index.get(o.category)
                if rankings:
                    b = run.baselines
                    ok = paper.suggestable
                    b["frequency"].append(rank_of(paper.base_rate, index, ok))
                    b["parent_only"].append(rank_of(scores.occurrence, index, ok))
                    b["no_position"].append(rank_of(options.lambda1 * scores.occurrence * scores.surface, index, ok))
                    b["no_backoff"].append(rank_of(plain.score(query).total, plain.index.get(o.category),
                                                   plain.suggestable))
                for spec in specs:
                    measure_query(run.engines[spec.name], engines[spec.name], paper_rule, query, scene, o, corpus,
                             periods, rankings)
    return run


def measure_query(out: EngineRun, engine, paper_rule: Engine, query: ContextQuery, scene: Scene,
                  o: ObjectInstance, corpus: Corpus, periods: ModelPeriods, timed: bool) -> None:
    """One held-out query asked of one engine: its rank, its orientation record and (``timed``) the time of the
    study server's request."""
    if timed:
        started = time.perf_counter()
        engine.suggest(query, "full", top=TIMED_TOP)
        out.seconds.append(time.perf_counter() - started)
    rank, full, basic, scores = _rank_and_poses(engine, query, o.category)
    out.ranks.append(rank)
    if full is None:
        return
    placed = {"full": full, "canonical": basic}
    if type(engine) is Engine and scores is not None:  # the paper's engine: its own rule too
        index = engine.index[o.category]
        faces, alphas, _ = paper_rule.choose_poses(scores, "full", [index])
        placed["paper"] = poses.placement(scores.prepared.point, scores.prepared.normal, faces[0],
                                          engine.size[index], float(alphas[0]))
    if hasattr(engine, "frame_poses") and getattr(engine, "frames", None) is not None and scores is not None:
        index = engine.index[o.category]  # the frame classifier's choice, whether or not the engine turns by it
        faces, alphas, _ = engine.frame_poses(scores, [index])
        placed["frames"] = poses.placement(scores.prepared.point, scores.prepared.normal, faces[0],
                                           engine.size[index], float(alphas[0]))
    period, source = periods.of(o.model_id, o.category, tuple(o.scaled_size()[[0, 2]]))
    record = _orientation_record(placed, scene, o, corpus, period, source, query.normal)
    if hasattr(engine, "frame_headings") and scores is not None:  # the ceiling of choosing a frame per query
        from ..engines.learned.training import frame_errors

        index = engine.index[o.category]
        _, _, proposed = engine.frame_headings(scores, np.array([index]))
        record["oracle_folded"] = float(min(frame_errors(engine, scores, index, o.transform, proposed[0], period)))
    out.records.append(record)


def _orientation_record(placed: dict[str, np.ndarray], scene: Scene, o: ObjectInstance, corpus: Corpus,
                        period: float, source: str, normal) -> dict:
    """How far each placement of ``placed`` (pose name → 4×4) is from the object's true pose."""
    table = _nearest_table(scene, o, corpus)
    size = np.asarray(o.size, dtype=float)
    record = {"category": o.category, "period": period, "period_source": source, "chair_at_table": table is not None}
    for pose, placement in placed.items():
        record[f"{pose}_front"] = front_angle_deg(placement, o.transform)
        record[f"{pose}_face"] = attachment_face(placement, normal) == o.attachment_face
        record[f"{pose}_folded"] = pose_error_deg(placement, o.transform, period)
        if table is not None:
            record[f"{pose}_facing"] = _facing_error_deg(placement, size, table, normal)
    return record


def _orientation(records: list[dict], pose: str) -> dict:
    rs = [r for r in records if f"{pose}_folded" in r]
    out = orientation_summary([r[f"{pose}_front"] for r in rs], [r[f"{pose}_folded"] for r in rs])
    out["face_correct"] = float(np.mean([r[f"{pose}_face"] for r in rs])) if rs else 0.0
    return out


def engine_figures(ranks: list[float], records: list[dict]) -> dict:
    """An engine's figures: ranking in both modes (the ranking does not depend on the mode), orientation of
    its full mode with the canonical pose (and the paper's rule, the frame classifier's choice and the frame
    oracle where measured) beside."""
    full = summary(ranks)
    full.update(_orientation(records, "full"))
    full["canonical"] = _orientation(records, "canonical")
    for pose in ("paper", "frames"):
        if records and f"{pose}_folded" in records[0]:
            full[pose] = _orientation(records, pose)
    oracle = [r["oracle_folded"] for r in records if "oracle_folded" in r]
    if oracle:
        full["frame_oracle"] = {"orient_folded_within_15": float(np.mean(np.array(oracle) <= 15)),
                                "orient_folded_within_45": float(np.mean(np.array(oracle) <= 45)),
                                "orient_median_deg": float(np.median(oracle)), "orient_n": len(oracle)}
    return {"modes": {"basic": summary(ranks), "full": full}}


def _poses_of(records: list[dict]) -> tuple[str, ...]:
    return tuple(p for p in POSES if records and f"{p}_folded" in records[0])


def _categories(records: list[dict], ranks: dict[str, list[float]] | None = None) -> dict:
    """Per category the engine placed: the orientation of each pose and (given ``ranks``) its MRR and top-1."""
    by: dict[str, list[dict]] = {}
    for r in records:
        by.setdefault(r["category"], []).append(r)
    out = {}
    for category, rs in sorted(by.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        out[category] = {"n": len(rs), "period": float(Counter(r["period"] for r in rs).most_common(1)[0][0])}
        for pose in _poses_of(rs):
            folded = np.array([r[f"{pose}_folded"] for r in rs])
            out[category][f"{pose}_folded_within_45"] = float(np.mean(folded <= 45))
            out[category][f"{pose}_median_deg"] = float(np.median(folded))
    for category, rs in (ranks or {}).items():  # the ranking of categories the engine could place
        if category in out:
            m = summary(rs)
            out[category].update({"mrr": m["mrr"], "top1": m["top1"], "queries": len(rs)})
    return out


def _chairs(records: list[dict]) -> dict:
    rs = [r for r in records if r["chair_at_table"]]
    out: dict = {"n": len(rs)}
    for pose in _poses_of(records):
        out[f"{pose}_facing_within_45"] = float(np.mean([r[f"{pose}_facing"] <= 45 for r in rs])) if rs else 0.0
        out[f"{pose}_folded_within_45"] = float(np.mean([r[f"{pose}_folded"] <= 45 for r in rs])) if rs else 0.0
    return out


def ranks_by_category(run: Run, name: str) -> dict[str, list[float]]:
    by: dict[str, list[float]] = {}
    for category, rank in zip(run.categories, run.engines[name].ranks, strict=True):
        by.setdefault(category, []).append(rank)
    return by


def paired_difference(first: list[float], other: list[float], groups: list[int], resamples: int = 1000,
                      seed: int = 0) -> dict:
    """The difference of MRR (other − first) over the same queries, with a 95% percentile interval from a
    bootstrap that resamples scene groups (near-copies together: the unit the folds keep apart), both engines'
    queries of a group at once."""
    a, b = 1.0 / np.asarray(first, dtype=float), 1.0 / np.asarray(other, dtype=float)
    ids, cluster = np.unique(np.asarray(groups), return_inverse=True)
    diff_sum = np.bincount(cluster, weights=b - a, minlength=len(ids))
    count = np.bincount(cluster, minlength=len(ids)).astype(float)
    draws = np.random.default_rng(seed).integers(0, len(ids), size=(resamples, len(ids)))
    boot = diff_sum[draws].sum(axis=1) / np.maximum(count[draws].sum(axis=1), 1.0)
    return {"mrr_difference": float((b - a).mean()), "low": float(np.percentile(boot, 2.5)),
            "high": float(np.percentile(boot, 97.5)), "resamples": resamples, "unit": "scene group",
            "groups": int(len(ids)), "queries": int(len(a))}


def _timing(seconds: list[float]) -> dict:
    if not seconds:
        return {}
    ms = 1000 * np.asarray(seconds)
    return {"query_p50_ms": float(np.percentile(ms, 50)), "query_p95_ms": float(np.percentile(ms, 95))}


def _engine_blocks(run: Run, specs: list[EngineSpec], resamples: int, seed: int) -> dict[str, dict]:
    """Each engine's figures by name; each after the first with its paired MRR difference from the first."""
    first = specs[0].name
    blocks = {}
    for spec in specs:
        er = run.engines[spec.name]
        block = {**engine_figures(er.ranks, er.records), **_timing(er.seconds), "version": spec.kind.version,
                 "options": {k: v for k, v in spec.raw.items() if k != "name"},
                 "chairs_at_tables": _chairs(er.records),
                 "categories": _categories(er.records, ranks_by_category(run, spec.name))}
        if spec.name != first:
            block["vs_first"] = {"engine": first, **paired_difference(run.engines[first].ranks, er.ranks, run.groups,
                                                                      resamples, seed)}
        blocks[spec.name] = block
    return blocks


def _ablations(corpus: Corpus, main_folds: list[np.ndarray], options: EngineOptions, periods: ModelPeriods,
               progress, specs: list[EngineSpec], run: Run, scene_type: str) -> dict[str, dict]:
    """Per variant of :data:`ABLATIONS`: the paper engine's full-mode orientation (degrees) and chairs at tables."""
    out = {}
    same = [sp for sp in specs if sp.name == "paper" and sp.config == options]
    paper_records = run.engines["paper"].records if same else None
    for name, fit_options in ABLATIONS.items():
        if fit_options or paper_records is None:
            variant = run_folds(corpus, main_folds, options, periods, progress, fit_options,
                                rankings=False, scene_type=scene_type).engines["paper"].records
        else:
            variant = paper_records
        out[name] = {**_orientation(variant, "full"), "chairs_at_tables": _chairs(variant)}
    return out


def _ungrouped(corpus: Corpus, plain_folds: list[np.ndarray], options: EngineOptions, periods: ModelPeriods,
               progress, spec: EngineSpec, seed: int, scene_type: str) -> dict:
    """The figures of engine ``spec`` on plain k-fold by scene (near-copies not kept together)."""
    plain = run_folds(corpus, plain_folds, options, periods, progress, specs=[spec], seed=seed,
                      scene_type=scene_type)
    er = plain.engines[spec.name]
    return {"queries": len(plain.groups), **engine_figures(er.ranks, er.records),
            "baselines": {b: summary(r) for b, r in plain.baselines.items()},
            "chairs_at_tables": _chairs(er.records)}


def evaluate(corpus: Corpus, folds: int = 5, seed: int = 0, options: EngineOptions | None = None,
             progress: Callable[[Iterable, str], Iterable] | None = None, group_similar: bool = True,
             periods: ModelPeriods | None = None, ablations: bool = False, engines: list[EngineSpec] | None = None,
             resamples: int = 1000, scene_type: str = DEFAULT_SCENE_TYPE) -> dict:
    """Run the k-fold evaluation; returns the JSON-ready summary (see the CLI's ``evaluate --json``).

    ``engines`` (default: the paper's, with ``options``) are each trained on every fold's training scenes and
    asked the same held-out queries; the first engine's figures are the top level, every engine's are under
    ``"engines"``, each after the first with the paired bootstrap interval of its MRR difference from the first
    (``"vs_first"``, :func:`paired_difference`). The baselines come from the paper's priors of each fold.
    With ``group_similar`` the main figures come from folds that keep near-copies together and the plain k-fold
    figures of the first engine are added under ``"ungrouped"``; without it only plain k-fold by scene is run.
    With ``ablations`` every variant of :data:`ABLATIONS` is trained and measured on the main folds too
    (``"ablations"``: the paper engine's full-mode orientation summary and the chairs beside tables of each).

    ``scene_type``: what a query says of its room — ``inferred`` (the default) from the objects left once the
    queried one is removed, as a participant's scene would give it, or ``given``, the scene's own type as its corpus
    set it (Stanford's was inferred from every object, the queried one too: it tells that a Study has a desk when
    the desk is the object asked about) — see :mod:`scenesuggest.suggestion.held_out`."""
    check_scene_type(scene_type)
    progress = progress or (lambda items, label="": items)
    options = options or EngineOptions()
    specs = checked_specs(engines, options)
    if periods is None:
        periods = corpus_periods(corpus.models.values(), progress)
    groups = similar_groups(corpus.scenes) if group_similar else list(range(len(corpus.scenes)))
    plain_folds = folds_of(len(corpus.scenes), folds, seed)
    main_folds = grouped_folds(groups, folds, seed) if group_similar else plain_folds
    run = run_folds(corpus, main_folds, options, periods, progress, specs=specs, groups=groups, seed=seed,
               scene_type=scene_type)
    first = specs[0].name
    blocks = _engine_blocks(run, specs, resamples, seed)
    top = blocks[first]
    result = {
        "source": corpus.source, "folds": folds, "seed": seed, "scene_type": scene_type, "queries": len(run.groups),
        "skipped": run.skipped,
        "engine": first, "modes": top["modes"], "baselines": {b: summary(r) for b, r in run.baselines.items()},
        "grouping": {"group_similar": group_similar, "groups": len(set(groups)),
                     "scenes_with_near_copies": int(sum(n for n in Counter(groups).values() if n > 1))},
        "period_sources": dict(Counter(r["period_source"] for r in run.engines[first].records)),
        "categories": top["categories"], "chairs_at_tables": top["chairs_at_tables"], "engines": blocks,
    }
    if ablations:
        result["ablations"] = _ablations(corpus, main_folds, options, periods, progress, specs, run, scene_type)
    if group_similar:
        result["ungrouped"] = _ungrouped(corpus, plain_folds, options, periods, progress, specs[0], seed, scene_type)
    return result
