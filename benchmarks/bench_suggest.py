"""Suggestion benchmark: training time, priors size, query latency, memory, and the speed-up over the
straightforward per-(reference, category) scorer of naive_scorer.py, measured in the same run on the same queries.

Queries: held-out support edges of Stanford scenes with 10–60 objects (the object is removed and the engine
is asked at its contact point), like the offline evaluation. A query is what the study server asks: full mode,
every category ranked, the best TOP placed and oriented (``p*_ms``); ``p95_all_placed_ms`` places every category.
The naive scorer computes the same: every category's score, and the orientation of the same TOP.
The top level is the paper's engine; ``engines`` has every engine asked (``--engine``, default paper, frequency and
learned: trained on the corpus, its training time and file size beside) the same queries in the same way, with
``lightgbm`` for the learned engine: the milliseconds of each query spent in its LightGBM models, and ``frames``: the
same file turning suggestions by its frame classifier (``frames = true``); ``again``: the same queries asked a second
time, once the engine has made and kept its look-ups of the paper's statistics for them (what a server that has
answered such queries before pays). ``http`` is the overhead of the http engine over a local external engine — the
paper engine served by ``scenesuggest engine serve`` in a process of its own on loopback: per query, the http
engine's time minus the time the external engine says (Server-Timing) it took from reading the query to writing its
answer.
Budgets (2 cores): p95 ≤ 5 ms per engine, http overhead p95 ≤ 3 ms, training ≤ 30 s (paper) and ≤ 120 s
(learned), priors file ≤ 50 MB, speed-up ≥ 20×.
Usage: .venv/bin/python benchmarks/bench_suggest.py [--data ../shared/data] [--queries 600] [--naive 25]
       [--engine NAME …] [--no-http]
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
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)

ROOT = Path(__file__).resolve().parents[1]
TOP = 40  # the study server's list


def naive_query(naive, query) -> None:
    """What the engine does for one query, the straightforward way: all scores, then the TOP's headings."""
    scores = naive.scores(query)
    engine = naive.engine
    order = np.lexsort((engine.name_order, -scores))[:TOP]
    faces = engine.face_indices(engine.prepare(query), "full", order)
    for i, face in zip(order, faces, strict=True):
        naive.heading_scores(query, int(i), int(face))


def percentiles(values) -> dict:
    a = np.asarray(values)
    return {"p50_ms": round(float(np.percentile(a, 50)), 3), "p95_ms": round(float(np.percentile(a, 95)), 3),
            "p99_ms": round(float(np.percentile(a, 99)), 3), "max_ms": round(float(a.max()), 3)}


def parse_args() -> argparse.Namespace:
    """The command line: shared data folder, query counts, seed, engines to time, and whether to time http."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", default=os.environ.get("SCENESUGGEST_SHARED_DATA", ROOT.parent / "shared" / "data"))
    parser.add_argument("--queries", type=int, default=600)
    parser.add_argument("--naive", type=int, default=25, help="queries timed with the naive scorer")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--engine", action="append", dest="engines",
                        help="an engine to time besides the paper's (default: frequency and learned)")
    parser.add_argument("--no-http", action="store_true", help="leave out the http engine's overhead")
    return parser.parse_args()


def fit_priors(corpus) -> tuple:
    """The paper's priors fitted on the corpus, saved and loaded again: (priors, train s, load s, file MB)."""
    from scenesuggest.learning.priors import Priors

    t = time.perf_counter()
    priors = Priors.fit(corpus.scenes, corpus.taxonomy)
    train_s = time.perf_counter() - t
    with tempfile.TemporaryDirectory() as tmp:
        path = priors.save(Path(tmp) / "priors.npz")
        priors_mb = path.stat().st_size / 2**20
        t = time.perf_counter()
        priors = Priors.load(path)
        load_s = time.perf_counter() - t
    return priors, train_s, load_s, priors_mb


def held_out_queries(corpus, count: int, seed: int) -> list:
    """Up to ``count`` queries of scenes with 10–60 objects, made as ``evaluate`` makes them (the object removed, asked
    at its contact, the room's type inferred without it; no placeholder object)."""
    from scenesuggest.suggestion import held_out

    rng = np.random.default_rng(seed)
    queries = [q for s in corpus.scenes if 10 <= len(s) <= 60 for q, _ in held_out.held_out_queries(s, corpus.taxonomy)]
    picks = rng.choice(len(queries), size=min(count, len(queries)), replace=False)
    return [queries[i] for i in picks]


def time_paper(engine, queries) -> tuple[list, list]:
    """The paper engine's ms per query: the TOP placed for every query, and every category placed for the first 100."""
    engine.suggest(queries[0], "full", top=TOP)  # import-time and first-touch costs are not query costs
    latencies, all_placed = [], []
    for q in queries:
        t = time.perf_counter()
        engine.suggest(q, "full", top=TOP)
        latencies.append((time.perf_counter() - t) * 1000)
    for q in queries[:100]:
        t = time.perf_counter()
        engine.suggest(q, "full")
        all_placed.append((time.perf_counter() - t) * 1000)
    return latencies, all_placed


def versus_naive(naive, engine, compared) -> tuple[list, list]:
    """The naive scorer's and the engine's ms for each compared query, the naive KDEs built beforehand."""
    for q in compared:  # build the naive KDEs first: only evaluation is compared
        naive.scores(q)
    naive_ms, fast_ms = [], []
    for q in compared:
        t = time.perf_counter()
        naive_query(naive, q)
        naive_ms.append((time.perf_counter() - t) * 1000)
        t = time.perf_counter()
        engine.suggest(q, "full", top=TOP)
        fast_ms.append((time.perf_counter() - t) * 1000)
    return naive_ms, fast_ms


def main() -> int:
    args = parse_args()
    stanford_dir = Path(args.data) / "stanford_scene_db"
    if not stanford_dir.is_dir():
        print(json.dumps({"benchmark": "suggest", "error": f"no Stanford corpus at {stanford_dir}"}))
        return 1

    from scenesuggest.corpora import load_corpus
    from scenesuggest.suggestion.suggest import Engine

    corpus = load_corpus(f"stanford:{stanford_dir}")
    priors, train_s, load_s, priors_mb = fit_priors(corpus)
    engine = Engine(priors)
    queries = held_out_queries(corpus, args.queries, args.seed)
    from naive_scorer import NaiveScorer

    latencies, all_placed = time_paper(engine, queries)
    naive_ms, fast_ms = versus_naive(NaiveScorer(engine), engine, queries[: args.naive])

    others = {}
    for name in args.engines or ["frequency", "learned"]:
        others[name] = time_engine(name, corpus, priors, queries, Path(tempfile.mkdtemp()))
    http = {} if args.no_http else http_overhead(priors, queries)

    print(json.dumps({
        "benchmark": "suggest",
        "queries": len(latencies),
        "candidates": len(engine.candidates),
        "mode": "full",
        "top": TOP,
        **percentiles(latencies),
        "p95_all_placed_ms": round(float(np.percentile(all_placed, 95)), 3),
        "train_s": round(train_s, 2),
        "load_s": round(load_s, 3),
        "priors_mb": round(priors_mb, 2),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "naive_queries": len(naive_ms),
        "naive_query_mean_ms": round(float(np.mean(naive_ms)), 2),
        "engine_query_mean_ms": round(float(np.mean(fast_ms)), 3),
        "speedup_vs_naive": round(float(np.mean(naive_ms) / np.mean(fast_ms)), 1) if naive_ms else math.nan,
        "engines": {"paper": {**percentiles(latencies), "train_s": round(train_s, 2), "file_mb": round(priors_mb, 2)},
                    **others},
        "http": http,
    }, indent=1))
    return 0


def time_engine(name: str, corpus, priors, queries, tmp: Path) -> dict:
    """An engine trained on the corpus (or answering from its priors) asked every query as the server asks."""
    from scenesuggest import engines
    from scenesuggest.assets.symmetry import corpus_periods
    from scenesuggest.engines.protocol import LoadContext

    spec = engines.configure({"name": name})
    kind = spec.kind
    out: dict = {}
    if hasattr(kind, "from_priors"):
        engine = kind.from_priors(spec.config, priors)
    else:
        periods = corpus_periods(corpus.models.values())
        t = time.perf_counter()
        info = kind.train(spec.config, corpus.scenes, corpus.taxonomy, tmp / f"{name}.npz", periods=periods)
        out["train_s"] = round(time.perf_counter() - t, 2)
        out["file_mb"] = round(info["bytes"] / 2**20, 2)
        t = time.perf_counter()
        engine = kind.load(kind.configure({"file": info["out"]}), LoadContext(tmp / "priors.npz"))
        out["load_s"] = round(time.perf_counter() - t, 3)
    timed = _latencies(engine, queries)
    if name == "learned":  # the same file, loaded afresh, turning suggestions by its frame classifier
        del engine
        framed = kind.load(kind.configure({"file": info["out"], "frames": True}), LoadContext(tmp / "priors.npz"))
        out["frames"] = _latencies(framed, queries)
    return {**timed, **out}


def _latencies(engine, queries) -> dict:
    """The percentiles of the engine's time per query (after one to warm it), and of the time inside its LightGBM
    models (``lightgbm``) where it has any."""
    engine.suggest(queries[0], "full", top=TOP)
    inside = _timed_models(engine)
    latencies, models_ms = [], []
    for q in queries:
        inside[0] = 0.0
        latencies.append(_ms(engine, q))
        models_ms.append(inside[0])
    out = percentiles(latencies)
    if any(models_ms):  # the time inside the engine's trained models (LightGBM's predict), per query
        out["lightgbm"] = _p50_p95(models_ms)
    out["again"] = _p50_p95([_ms(engine, q) for q in queries])
    return out


def _ms(engine, query) -> float:
    """Milliseconds the engine takes to answer ``query`` as the server asks it."""
    t = time.perf_counter()
    engine.suggest(query, "full", top=TOP)
    return (time.perf_counter() - t) * 1000


def _p50_p95(values) -> dict:
    return {k: v for k, v in percentiles(values).items() if k in ("p50_ms", "p95_ms")}


def _timed_models(engine) -> list[float]:
    """Wrap the predict of each LightGBM model the engine holds (the learned engine's ranker and frame classifier)
    so that the milliseconds spent in them add up in the returned one-element list."""
    total = [0.0]
    for name in ("ranker", "frames"):
        model = getattr(engine, name, None)
        if model is None or not hasattr(model, "predict"):
            continue

        def timed(*args, _predict=model.predict, **kwargs):
            t = time.perf_counter()
            try:
                return _predict(*args, **kwargs)
            finally:
                total[0] += (time.perf_counter() - t) * 1000

        model.predict = timed
    return total


def http_overhead(priors, queries) -> dict:
    """The http engine's time over the paper engine's own for the same query (module docstring)."""
    import subprocess

    from serverproc import free_port, wait_for_port

    from scenesuggest import engines
    from scenesuggest.engines.protocol import LoadContext

    with tempfile.TemporaryDirectory() as tmp:
        path = priors.save(Path(tmp) / "priors.npz")
        port = free_port()
        server = subprocess.Popen([sys.executable, "-m", "scenesuggest.cli", "engine", "serve", "paper", "--priors",
                                   str(path), "--port", str(port)], stderr=subprocess.DEVNULL)
        try:
            wait_for_port(port)
            http = engines.load(engines.configure({"name": "http", "url": f"http://127.0.0.1:{port}/",
                                                   "timeout_ms": 2000}), LoadContext(path))
            http.suggest(queries[0], "full", top=TOP)
            overhead, fallbacks = [], 0
            for q in queries:
                t = time.perf_counter()
                found = http.suggest(q, "full", top=TOP)
                total = (time.perf_counter() - t) * 1000
                if found.fallback is not None or http.last_server_ms() is None:
                    fallbacks += 1
                    continue
                overhead.append(total - http.last_server_ms())
        finally:
            server.kill()
            server.wait()
    return {"overhead_" + k: v for k, v in percentiles(overhead).items()} | {"fallbacks": fallbacks}


if __name__ == "__main__":
    sys.exit(main())
