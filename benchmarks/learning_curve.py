"""Learning curves: held-out MRR and orientation of each engine against the number of training scenes.

Grouped 5-fold Stanford (near-copies in one fold, as ``evaluate``), for each seed: in every fold, each engine is
trained on a growing share of the training folds' scene groups (the same groups for every engine; a smaller share
is a subset of a larger one) and asked every held-out query of the fold. Printed per engine and share: the mean
number of training scenes, MRR, top-1, and the full-mode orientation folded within 45° (and for the learned engine
``frames_orient_folded_within_45``: its frame classifier's choice, what ``frames = true`` shows), each as the median
and range over the seeds. Beside them, in-sample (the engine trained on every scene and asked the same queries, each
object removed from its scene as always): how far the same machinery gets when the answers were in its training
data — an upper bound the held-out figures approach only if more data helps.

Usage: .venv/bin/python benchmarks/learning_curve.py [--data ../shared/data] [--seeds 0,1,2]
       [--shares 0.25,0.5,0.75,1] [--engine paper --engine learned]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default=os.environ.get("SCENESUGGEST_SHARED_DATA", ROOT.parent / "shared" / "data"))
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--shares", default="0.25,0.5,0.75,1")
    parser.add_argument("--engine", action="append", dest="engines")
    args = parser.parse_args()
    stanford_dir = Path(args.data) / "stanford_scene_db"
    if not stanford_dir.is_dir():
        print(json.dumps({"benchmark": "learning_curve", "error": f"no Stanford corpus at {stanford_dir}"}))
        return 1
    from scenesuggest import engines
    from scenesuggest.assets.symmetry import corpus_periods
    from scenesuggest.corpora import load_corpus
    from scenesuggest.corpora.corpus import Corpus
    from scenesuggest.corpora.folds import grouped_folds, similar_groups
    from scenesuggest.evaluation.evaluate import run_folds
    from scenesuggest.suggestion.suggest import EngineOptions

    started = time.perf_counter()
    corpus = load_corpus(f"stanford:{stanford_dir}")
    periods = corpus_periods(corpus.models.values())
    groups = similar_groups(corpus.scenes)
    specs = [engines.configure({"name": n}) for n in (args.engines or ["paper", "learned"])]
    shares = [float(s) for s in args.shares.split(",")]
    seeds = [int(s) for s in args.seeds.split(",")]
    quiet = lambda items, label="": items  # noqa: E731
    points: dict[str, dict[float, list[dict]]] = {s.name: {share: [] for share in shares} for s in specs}
    for seed in seeds:
        rng = np.random.default_rng(seed)
        folds = grouped_folds(groups, 5, seed)
        for held in folds:
            held_set = set(held.tolist())
            train_groups = sorted({groups[i] for i in range(len(corpus.scenes)) if i not in held_set})
            order = [train_groups[k] for k in rng.permutation(len(train_groups))]
            for share in shares:
                kept = set(order[: max(1, round(share * len(order)))])
                keep = [i for i in range(len(corpus.scenes)) if i in held_set or groups[i] in kept]
                sub = Corpus(corpus.source, [corpus.scenes[i] for i in keep], corpus.models, corpus.taxonomy)
                local_held = np.array([k for k, i in enumerate(keep) if i in held_set])
                run = run_folds(sub, [local_held], EngineOptions(), periods, quiet, specs=specs, seed=seed,
                           rankings=False)
                for s in specs:
                    er = run.engines[s.name]
                    points[s.name][share].append(_figures(er.ranks, er.records, len(keep) - len(local_held)))
    in_sample = {s.name: _in_sample(s, corpus, periods) for s in specs}
    out = {"benchmark": "learning_curve", "seeds": seeds, "folds": 5, "scenes": len(corpus.scenes),
           "engines": {name: [_summary(share, runs) for share, runs in by_share.items()]
                       for name, by_share in points.items()},
           "in_sample": in_sample, "seconds": round(time.perf_counter() - started, 1)}
    print(json.dumps(out, indent=1))
    return 0


def _in_sample(spec, corpus, periods) -> dict:
    """The engine trained on every scene and asked about every scene (each object removed from it, as always)."""
    from scenesuggest.errors import SceneSuggestError
    from scenesuggest.evaluation.evaluate import EngineRun, fitted_engine, measure_query
    from scenesuggest.learning.priors import Priors
    from scenesuggest.suggestion.held_out import held_out_queries
    from scenesuggest.suggestion.suggest import Engine

    quiet = lambda items, label="": items  # noqa: E731
    priors = Priors.fit(corpus.scenes, corpus.taxonomy)
    paper = Engine(priors)
    engine = fitted_engine(spec, priors, corpus.scenes, corpus, 0, periods, quiet)
    out = EngineRun()
    for scene in corpus.scenes:
        for query, o in held_out_queries(scene, corpus.taxonomy):  # as evaluate asks them
            try:
                paper.score(query)
            except SceneSuggestError:  # bad data, skipped as evaluate skips it
                continue
            measure_query(out, engine, paper.with_options(orientation="paper"), query, scene, o, corpus, periods,
                          False)
    return _figures(out.ranks, out.records, len(corpus.scenes))


def _figures(ranks: list[float], records: list[dict], training_scenes: int) -> dict:
    r = np.asarray(ranks, dtype=float)
    out = {"training_scenes": training_scenes, "mrr": float(np.mean(1 / r)), "top1": float(np.mean(r <= 1)),
           "queries": len(r), "orient_folded_within_45": _within_45(records, "full")}
    if records and all("frames_folded" in x for x in records):
        out["frames_orient_folded_within_45"] = _within_45(records, "frames")
    return out


def _within_45(records: list[dict], pose: str) -> float:
    folded = np.array([x[f"{pose}_folded"] for x in records])
    return float(np.mean(folded <= 45)) if len(folded) else 0.0


def _summary(share: float, runs: list[dict]) -> dict:
    """Per seed the mean over folds, then the median and range over seeds."""
    per = len(runs) // 5
    seeds = [runs[5 * k: 5 * (k + 1)] for k in range(per)]
    out = {"share": share}
    for key in ("training_scenes", "mrr", "top1", "orient_folded_within_45", "frames_orient_folded_within_45"):
        if not all(key in run for run in runs):
            continue
        values = [float(np.average([f[key] for f in s], weights=[f["queries"] for f in s])) for s in seeds]
        out[key] = {"median": float(np.median(values)), "low": float(min(values)), "high": float(max(values))}
    return out


if __name__ == "__main__":
    sys.exit(main())
