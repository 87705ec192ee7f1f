"""Offline evaluation: k-fold by scene, one query per held-out support edge.

For every object of a held-out scene that rests on a parent, the object is removed (with everything it
supports), the engine is asked at its true contact point on its true parent with the true normal, and
the rank of its true category is recorded (edges whose contact lies far from the parent's box are bad
data, skipped and counted). A category never seen in training has no rank (reciprocal
rank 0). Ties count half: rank = 1 + (#scored higher) + (#scored equal)/2.

``full`` mode also places the true category; the angle between the predicted and the true front is
reported as the fractions within 15° and 45°. Baselines rank by: global category frequency
(``frequency``); P(|C on p| > k) alone (``parent_only``); the full score without back-off
(``no_backoff``); the score without the position term (``no_position``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

import numpy as np

from . import poses
from .corpora.corpus import Corpus
from .errors import SceneSuggestError
from .priors import Priors
from .suggest import ContextQuery, Engine, EngineOptions

BASELINES = ("frequency", "parent_only", "no_backoff", "no_position")


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


def folds_of(n_scenes: int, k: int, seed: int) -> list[np.ndarray]:
    order = np.random.default_rng(seed).permutation(n_scenes)
    return [np.sort(f) for f in np.array_split(order, k)]


def front_angle_deg(predicted: np.ndarray, truth: np.ndarray) -> float:
    a, b = poses.rotation_of(predicted)[:, 2], poses.rotation_of(truth)[:, 2]
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


def evaluate(corpus: Corpus, folds: int = 5, seed: int = 0, options: EngineOptions | None = None,
             progress: Callable[[Iterable, str], Iterable] | None = None) -> dict:
    """Run the k-fold evaluation; returns the JSON-ready summary (see the CLI's ``evaluate --json``)."""
    progress = progress or (lambda items, label="": items)
    options = options or EngineOptions()
    ranks: dict[str, list[float]] = {m: [] for m in ("basic", "full", *BASELINES)}
    angles: list[float] = []
    skipped = 0
    for held in progress(folds_of(len(corpus.scenes), folds, seed), "folds"):
        held_set = set(held.tolist())
        train = [s for i, s in enumerate(corpus.scenes) if i not in held_set]
        priors = Priors.fit(train, corpus.taxonomy)
        engine = Engine(priors, options)
        plain = engine.with_options(backoff=False)
        total_freq = engine.base_rate
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
                ranks["frequency"].append(rank_of(total_freq, index))
                ranks["parent_only"].append(rank_of(scores.occurrence, index))
                ranks["no_position"].append(rank_of(options.lambda1 * scores.occurrence * scores.surface, index))
                ranks["no_backoff"].append(rank_of(plain.score(query).total, plain.index.get(o.category)))
                if index is not None:
                    faces, alphas, _ = engine.choose_poses(scores, "full")
                    predicted = poses.placement(scores.prepared.point, scores.prepared.normal, faces[index],
                                                engine.size[index], float(alphas[index]))
                    angles.append(front_angle_deg(predicted, o.transform))
    full = summary(ranks["full"])
    a = np.array(angles)
    full["orient_within_15"] = float(np.mean(a <= 15)) if len(a) else 0.0
    full["orient_within_45"] = float(np.mean(a <= 45)) if len(a) else 0.0
    full["orient_n"] = int(len(a))
    return {
        "source": corpus.source, "folds": folds, "seed": seed, "queries": len(ranks["full"]),
        "skipped": skipped,
        "modes": {"basic": summary(ranks["basic"]), "full": full},
        "baselines": {b: summary(ranks[b]) for b in BASELINES},
    }


def format_evaluation(result: dict) -> str:
    """A human table of :func:`evaluate`'s result."""
    lines = [f"{result['source']}: {result['queries']} queries ({result['skipped']} skipped), "
             f"{result['folds']}-fold by scene, seed {result['seed']}",
             "", f"{'ranking':<14}{'MRR':>8}{'top-1':>8}{'top-5':>8}"]
    rows = [("basic", result["modes"]["basic"]), ("full", result["modes"]["full"])]
    rows += [(f"- {b}", result["baselines"][b]) for b in BASELINES]
    for name, m in rows:
        lines.append(f"{name:<14}{m['mrr']:>8.3f}{m['top1']:>8.3f}{m['top5']:>8.3f}")
    full = result["modes"]["full"]
    lines += ["", f"full-mode orientation of the true category ({full['orient_n']} placements): "
                  f"{100 * full['orient_within_15']:.1f}% within 15°, {100 * full['orient_within_45']:.1f}% within 45°"]
    return "\n".join(lines)
