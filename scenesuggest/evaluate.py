"""Offline evaluation: k-fold by scene, one query per held-out support edge.

For every object of a held-out scene that rests on a parent, the object is removed (with everything it
supports), the engine is asked at its true contact point on its true parent with the true normal, and
the rank of its true category is recorded (edges whose contact lies far from the parent's box are bad
data, skipped and counted). A category never seen in training has no rank (reciprocal
rank 0). Ties count half: rank = 1 + (#scored higher) + (#scored equal)/2.

Folds keep near-copies of a scene together (:mod:`.folds`; ``group_similar``, the default); the figures of
plain k-fold by scene are reported beside them under ``"ungrouped"``.

Orientation: the true category is also placed, in ``full`` mode and in the canonical pose that ``basic`` uses
(the geometric attachment face, no turn). Reported for each (:func:`orientation_summary`): the fractions within
15° and 45° of the angle between the predicted and the true front (``orient_within_*``, the unfolded figure),
the same for the rotation error folded by the model's rotational symmetry about its up axis
(``orient_folded_within_*``, :func:`~scenesuggest.pose_error.pose_error_deg`; periods from meshes, see
:mod:`.symmetry`) and the median folded error. Per category under ``"categories"``; chairs standing beside a
table or desk under ``"chairs_at_tables"`` (also: how often the suggested chair faces the nearest one).

Baselines rank by: global category frequency (``frequency``); P(|C on p| > k) alone (``parent_only``); the
full score without back-off (``no_backoff``); the score without the position term (``no_position``).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable

import numpy as np

from . import poses
from .corpora.corpus import Corpus
from .errors import SceneSuggestError
from .folds import folds_of, grouped_folds, similar_groups
from .pose_error import front_angle_deg, pose_error_deg
from .priors import Priors
from .scene import ObjectInstance, Scene
from .suggest import ContextQuery, Engine, EngineOptions
from .symmetry import ModelPeriods, corpus_periods

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
#: Poses whose orientation is measured: the engine's full mode, full mode with the paper's orientation rule, and
#: the canonical pose of basic mode.
POSES = ("full", "paper", "canonical")
TOLERANCES_DEG = (15, 45)

__all__ = ["evaluate", "format_evaluation", "folds_of", "rank_of", "summary", "orientation_summary"]


def rank_of(scores: np.ndarray, index: int | None) -> float:
    """1-based rank of ``index`` in ``scores`` (higher is better; ties count half); inf when absent."""
    if index is None:
        return math.inf
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


def _run(corpus: Corpus, folds: list[np.ndarray], options: EngineOptions, periods: ModelPeriods,
         progress, fit_options: dict | None = None, rankings: bool = True
         ) -> tuple[dict[str, list[float]], list[dict], int]:
    """Ranks per ranking, one orientation record per placed query, and the number of skipped edges
    (``rankings=False``: the baselines are not ranked, for orientation-only runs)."""
    ranks: dict[str, list[float]] = {m: [] for m in ("basic", "full", *BASELINES)}
    records: list[dict] = []
    skipped = 0
    for held in progress(folds, "folds"):
        held_set = set(held.tolist())
        train = [s for i, s in enumerate(corpus.scenes) if i not in held_set]
        engine = Engine(Priors.fit(train, corpus.taxonomy, **(fit_options or {})), options)
        plain = engine.with_options(backoff=False)
        paper = engine.with_options(orientation="paper")
        for i in held:
            scene = corpus.scenes[i]
            for o in scene:
                if o.parent is None or o.contact_point is None or o.contact_normal is None:
                    continue
                query = ContextQuery(scene.without(o.id), o.parent, o.contact_point, o.contact_normal,
                                     scene_type=scene.scene_type)
                try:
                    scores = engine.score(query)
                except SceneSuggestError:  # a contact far from its parent's box: bad data, not a query
                    skipped += 1
                    continue
                index = engine.index.get(o.category)
                r = rank_of(scores.total, index)
                ranks["basic"].append(r)
                ranks["full"].append(r)
                if rankings:
                    ranks["frequency"].append(rank_of(engine.base_rate, index))
                    ranks["parent_only"].append(rank_of(scores.occurrence, index))
                    ranks["no_position"].append(rank_of(options.lambda1 * scores.occurrence * scores.surface,
                                                        index))
                    ranks["no_backoff"].append(rank_of(plain.score(query).total, plain.index.get(o.category)))
                if index is not None:
                    records.append(_orientation_record(engine, paper, scores, index, scene, o, corpus, periods))
    return ranks, records, skipped


def _orientation_record(engine: Engine, paper: Engine, scores, index: int, scene: Scene, o: ObjectInstance,
                        corpus: Corpus, periods: ModelPeriods) -> dict:
    prep = scores.prepared
    period, source = periods.of(o.model_id, o.category, tuple(o.scaled_size()[[0, 2]]))
    table = _nearest_table(scene, o, corpus)
    record = {"category": o.category, "period": period, "period_source": source, "chair_at_table": table is not None}
    for pose, by, mode in (("full", engine, "full"), ("paper", paper, "full"), ("canonical", engine, "basic")):
        faces, alphas, _ = by.choose_poses(scores, mode, [index])
        placed = poses.placement(prep.point, prep.normal, faces[0], engine.size[index], float(alphas[0]))
        record[f"{pose}_front"] = front_angle_deg(placed, o.transform)
        record[f"{pose}_face"] = faces[0] == o.attachment_face
        record[f"{pose}_folded"] = pose_error_deg(placed, o.transform, period)
        if table is not None:
            record[f"{pose}_facing"] = _facing_error_deg(placed, engine.size[index], table, prep.normal)
    return record


def _orientation(records: list[dict], pose: str) -> dict:
    out = orientation_summary([r[f"{pose}_front"] for r in records], [r[f"{pose}_folded"] for r in records])
    out["face_correct"] = float(np.mean([r[f"{pose}_face"] for r in records])) if records else 0.0
    return out


def _modes(ranks: dict[str, list[float]], records: list[dict]) -> dict:
    full = summary(ranks["full"])
    full.update(_orientation(records, "full"))
    full["paper"] = _orientation(records, "paper")
    full["canonical"] = _orientation(records, "canonical")
    return {"modes": {"basic": summary(ranks["basic"]), "full": full},
            "baselines": {b: summary(ranks[b]) for b in BASELINES}}


def _categories(records: list[dict]) -> dict:
    by: dict[str, list[dict]] = {}
    for r in records:
        by.setdefault(r["category"], []).append(r)
    out = {}
    for category, rs in sorted(by.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        out[category] = {"n": len(rs), "period": float(Counter(r["period"] for r in rs).most_common(1)[0][0])}
        for pose in POSES:
            folded = np.array([r[f"{pose}_folded"] for r in rs])
            out[category][f"{pose}_folded_within_45"] = float(np.mean(folded <= 45))
            out[category][f"{pose}_median_deg"] = float(np.median(folded))
    return out


def _chairs(records: list[dict]) -> dict:
    rs = [r for r in records if r["chair_at_table"]]
    out: dict = {"n": len(rs)}
    for pose in POSES:
        out[f"{pose}_facing_within_45"] = float(np.mean([r[f"{pose}_facing"] <= 45 for r in rs])) if rs else 0.0
        out[f"{pose}_folded_within_45"] = float(np.mean([r[f"{pose}_folded"] <= 45 for r in rs])) if rs else 0.0
    return out


def evaluate(corpus: Corpus, folds: int = 5, seed: int = 0, options: EngineOptions | None = None,
             progress: Callable[[Iterable, str], Iterable] | None = None, group_similar: bool = True,
             periods: ModelPeriods | None = None, ablations: bool = False) -> dict:
    """Run the k-fold evaluation; returns the JSON-ready summary (see the CLI's ``evaluate --json``).

    With ``group_similar`` the main figures come from folds that keep near-copies together and the plain
    k-fold figures are added under ``"ungrouped"``; without it only plain k-fold by scene is run. With
    ``ablations`` every variant of :data:`ABLATIONS` is trained and measured on the main folds too
    (``"ablations"``: the full-mode orientation summary and the chairs beside tables of each)."""
    progress = progress or (lambda items, label="": items)
    options = options or EngineOptions()
    if periods is None:
        periods = corpus_periods(corpus.models.values(), progress)
    groups = similar_groups(corpus.scenes) if group_similar else list(range(len(corpus.scenes)))
    plain_folds = folds_of(len(corpus.scenes), folds, seed)
    main_folds = grouped_folds(groups, folds, seed) if group_similar else plain_folds
    ranks, records, skipped = _run(corpus, main_folds, options, periods, progress)
    result = {
        "source": corpus.source, "folds": folds, "seed": seed, "queries": len(ranks["full"]),
        "skipped": skipped,
        **_modes(ranks, records),
        "grouping": {"group_similar": group_similar, "groups": len(set(groups)),
                     "scenes_with_near_copies": int(sum(n for n in Counter(groups).values() if n > 1))},
        "period_sources": dict(Counter(r["period_source"] for r in records)),
        "categories": _categories(records),
        "chairs_at_tables": _chairs(records),
    }
    if ablations:
        result["ablations"] = {}
        for name, fit_options in ABLATIONS.items():
            if fit_options:
                _, variant, _ = _run(corpus, main_folds, options, periods, progress, fit_options, rankings=False)
            else:
                variant = records
            result["ablations"][name] = {**_orientation(variant, "full"), "chairs_at_tables": _chairs(variant)}
    if group_similar:
        plain_ranks, plain_records, _ = _run(corpus, plain_folds, options, periods, progress)
        result["ungrouped"] = {"queries": len(plain_ranks["full"]), **_modes(plain_ranks, plain_records),
                               "chairs_at_tables": _chairs(plain_records)}
    return result


def _ranking_rows(block: dict) -> list[str]:
    rows = [("basic", block["modes"]["basic"]), ("full", block["modes"]["full"])]
    rows += [(f"- {b}", block["baselines"][b]) for b in BASELINES]
    return [f"{name:<14}{m['mrr']:>8.3f}{m['top1']:>8.3f}{m['top5']:>8.3f}" for name, m in rows]


def _orientation_rows(full: dict) -> list[str]:
    lines = [f"{'orientation':<14}{'≤15°':>8}{'≤45°':>8}{'folded ≤15°':>13}{'≤45°':>8}{'median':>9}"]
    for name, m in (("full", full), ("paper's rule", full["paper"]), ("canonical", full["canonical"])):
        lines.append(f"{name:<14}{100 * m['orient_within_15']:>7.1f}%{100 * m['orient_within_45']:>7.1f}%"
                     f"{100 * m['orient_folded_within_15']:>12.1f}%{100 * m['orient_folded_within_45']:>7.1f}%"
                     f"{m['orient_median_deg']:>8.1f}°")
    return lines


def format_evaluation(result: dict, by_category: bool = False, top: int = 30) -> str:
    """A human table of :func:`evaluate`'s result (``by_category``: also the per-category orientation table)."""
    grouping = result["grouping"]
    how = (f"{result['folds']}-fold by scene, near-copies kept together ({grouping['groups']} groups; "
           f"{grouping['scenes_with_near_copies']} scenes have near-copies)" if grouping["group_similar"]
           else f"{result['folds']}-fold by scene")
    lines = [f"{result['source']}: {result['queries']} queries ({result['skipped']} skipped), {how}, "
             f"seed {result['seed']}", "", f"{'ranking':<14}{'MRR':>8}{'top-1':>8}{'top-5':>8}"]
    lines += _ranking_rows(result)
    full = result["modes"]["full"]
    sources = ", ".join(f"{n} from {s}" for s, n in sorted(result["period_sources"].items()))
    lines += ["", f"orientation of the true category ({full['orient_n']} placements; symmetry periods: {sources})"]
    lines += _orientation_rows(full)
    chairs = result["chairs_at_tables"]
    if chairs["n"]:
        lines += ["", f"chairs beside a table or desk ({chairs['n']}): facing it within 45° — full "
                      f"{100 * chairs['full_facing_within_45']:.1f}%, paper's rule "
                      f"{100 * chairs['paper_facing_within_45']:.1f}%, canonical "
                      f"{100 * chairs['canonical_facing_within_45']:.1f}%"]
    if "ungrouped" in result:
        plain = result["ungrouped"]
        lines += ["", f"plain {result['folds']}-fold by scene (near-copies may straddle folds; {plain['queries']} "
                      "queries)", f"{'ranking':<14}{'MRR':>8}{'top-1':>8}{'top-5':>8}"]
        lines += _ranking_rows(plain)
        lines += [""] + _orientation_rows(plain["modes"]["full"])
    if "ablations" in result:
        lines += ["", f"{'orientation ablations':<38}{'folded ≤15°':>12}{'≤45°':>8}{'median':>9}{'chairs facing':>15}"]
        rows = [(name, m, m["chairs_at_tables"]["full_facing_within_45"]) for name, m in result["ablations"].items()]
        rows += [("the paper's rule", full["paper"], chairs["paper_facing_within_45"]),
                 ("canonical pose (basic)", full["canonical"], chairs["canonical_facing_within_45"])]
        for name, m, facing in rows:
            lines.append(f"{name:<38}{100 * m['orient_folded_within_15']:>11.1f}%"
                         f"{100 * m['orient_folded_within_45']:>7.1f}%{m['orient_median_deg']:>8.1f}°"
                         f"{100 * facing:>14.1f}%")
    if by_category:
        lines += ["", f"{'folded ≤45°':<24}{'n':>6}{'period':>8}{'full':>8}{'paper':>8}{'canonical':>11}"]
        for name, c in list(result["categories"].items())[:top]:
            lines.append(f"{name:<24}{c['n']:>6}{c['period']:>7.0f}°{100 * c['full_folded_within_45']:>7.1f}%"
                         f"{100 * c['paper_folded_within_45']:>7.1f}%{100 * c['canonical_folded_within_45']:>10.1f}%")
        if len(result["categories"]) > top:
            lines.append(f"… {len(result['categories']) - top} more categories (use --json for all)")
    return "\n".join(lines)
