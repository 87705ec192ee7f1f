"""Suggestion benchmark: training time, priors size, query latency (full mode, every category), memory, and the
speed-up over a straightforward per-pair scipy.stats.gaussian_kde scorer measured in the same run.

Queries: held-out support edges of Stanford scenes with 10–60 objects (the object is removed and the engine
is asked at its contact point), like the offline evaluation. Budgets (2 cores): p95 ≤ 10 ms, training
≤ 30 s, priors file ≤ 50 MB.
Usage: .venv/bin/python benchmarks/bench_suggest.py [--data ../shared/data] [--queries 600] [--naive 25]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def naive_position(engine, prep, kdes) -> np.ndarray:
    """Σ_r P_relpos the straightforward way: one scipy KDE per (reference, category) pair, evaluated one by one.
    KDE objects are built once and reused (fitting is not timed), densities normalised by the same peaks."""
    from scipy.stats import gaussian_kde

    from scenesuggest import poses
    from scenesuggest.observations import is_radial

    p = engine.priors
    out = np.zeros(len(engine.candidates))
    for ref, relation in prep.references:
        g = p.group_for(ref.category, prep.scene_type, relation, prep.surface_type)
        if g is None:
            continue
        delta = poses.plane_offset(prep.point, prep.normal, ref.transform, is_radial(ref.size))
        children, segs = p.segments(g)
        by_child = dict(zip(children.tolist(), segs.tolist(), strict=True))
        for i, e in enumerate(engine.stat_entity.tolist()):
            seg = by_child.get(e)
            if seg is None:
                continue
            if seg not in kdes:
                pts = p.pair_xy[p.seg_start[seg]:p.seg_start[seg] + p.seg_count[seg]].astype(float).T
                jitter = np.random.default_rng(seg).normal(0, 1e-3, pts.shape)  # scipy needs a full-rank cloud
                kdes[seg] = gaussian_kde(pts + jitter) if pts.shape[1] > 2 else None
            kde = kdes[seg]
            out[i] += float(kde(delta)[0]) if kde is not None else 0.0
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", default=os.environ.get("SCENESUGGEST_SHARED_DATA", ROOT.parent / "shared" / "data"))
    parser.add_argument("--queries", type=int, default=600)
    parser.add_argument("--naive", type=int, default=25, help="queries timed with the naive scorer")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    stanford_dir = Path(args.data) / "stanford_scene_db"
    if not stanford_dir.is_dir():
        print(json.dumps({"benchmark": "suggest", "error": f"no Stanford corpus at {stanford_dir}"}))
        return 1

    from scenesuggest.corpora import load_corpus
    from scenesuggest.priors import Priors
    from scenesuggest.suggest import ContextQuery, Engine

    corpus = load_corpus(f"stanford:{stanford_dir}")
    t = time.perf_counter()
    priors = Priors.fit(corpus.scenes, corpus.taxonomy)
    train_s = time.perf_counter() - t
    with tempfile.TemporaryDirectory() as tmp:
        path = priors.save(Path(tmp) / "priors.npz")
        priors_mb = path.stat().st_size / 2**20
        t = time.perf_counter()
        priors = Priors.load(path)
        load_s = time.perf_counter() - t
    engine = Engine(priors)

    rng = np.random.default_rng(args.seed)
    edges = [(s, o) for s in corpus.scenes if 10 <= len(s) <= 60 for o in s if o.parent is not None]
    picks = rng.choice(len(edges), size=min(args.queries, len(edges)), replace=False)
    queries = [ContextQuery(edges[i][0].without(edges[i][1].id), edges[i][1].parent, edges[i][1].contact_point,
                            edges[i][1].contact_normal) for i in picks]
    engine.suggest(queries[0], "full")  # import-time and first-touch costs are not query costs
    latencies = []
    for q in queries:
        t = time.perf_counter()
        engine.suggest(q, "full")
        latencies.append((time.perf_counter() - t) * 1000)
    fast_ms = [latencies[i] for i in range(min(args.naive, len(queries)))]

    kdes: dict = {}
    for q in queries[: args.naive]:  # build the naive KDEs first: only evaluation is compared
        naive_position(engine, engine.prepare(q), kdes)
    naive_ms = []
    for q in queries[: args.naive]:
        t = time.perf_counter()
        naive_position(engine, engine.prepare(q), kdes)
        naive_ms.append((time.perf_counter() - t) * 1000)

    lat = np.array(latencies)
    print(json.dumps({
        "benchmark": "suggest",
        "queries": len(lat),
        "candidates": len(engine.candidates),
        "mode": "full",
        "p50_ms": round(float(np.percentile(lat, 50)), 3),
        "p95_ms": round(float(np.percentile(lat, 95)), 3),
        "p99_ms": round(float(np.percentile(lat, 99)), 3),
        "max_ms": round(float(lat.max()), 3),
        "train_s": round(train_s, 2),
        "load_s": round(load_s, 3),
        "priors_mb": round(priors_mb, 2),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "naive_queries": len(naive_ms),
        "naive_position_only_mean_ms": round(float(np.mean(naive_ms)), 2),
        "engine_full_query_mean_ms": round(float(np.mean(fast_ms)), 3),
        "speedup_vs_naive": round(float(np.mean(naive_ms) / np.mean(fast_ms)), 1) if naive_ms else math.nan,
    }, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
