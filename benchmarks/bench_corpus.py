"""Corpus benchmark: load times of both corpora, asset build time per model, search latency.

Prints one JSON object. Budgets on a 2-core machine: Stanford load ≤ 5 s, search p95 ≤ 5 ms.
Usage: .venv/bin/python benchmarks/bench_corpus.py [--data ../shared/data] [--assets N]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed(fn):
    t = time.perf_counter()
    value = fn()
    return value, time.perf_counter() - t


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q / 100 * (len(values) - 1))))]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", default=os.environ.get("SCENESUGGEST_SHARED_DATA", ROOT.parent / "shared" / "data"))
    parser.add_argument("--assets", type=int, default=12, help="Stanford models to build (largest first)")
    args = parser.parse_args()
    stanford_dir = Path(args.data) / "stanford_scene_db"
    if not stanford_dir.is_dir():
        print(json.dumps({"benchmark": "corpus", "error": f"no Stanford corpus at {stanford_dir}"}))
        return 1

    from scenesuggest.assets.build import build_library
    from scenesuggest.corpora import load_corpus
    from scenesuggest.library.search import SearchIndex

    stanford, stanford_s = timed(lambda: load_corpus(f"stanford:{stanford_dir}"))
    ai2thor, ai2thor_s = timed(lambda: load_corpus("ai2thor"))

    meshes = sorted((m for m in stanford.models.values() if m.mesh), key=lambda m: -Path(m.mesh).stat().st_size)
    with tempfile.TemporaryDirectory() as tmp:
        stanford_build = build_library(stanford, Path(tmp) / "s", model_ids=[m.id for m in meshes[: args.assets]])
        demo_build = build_library(ai2thor, Path(tmp) / "a")

    index, index_s = timed(lambda: SearchIndex.build(stanford.models.values()))
    categories = sorted({m.category for m in stanford.models.values()})
    typed = [w[:n] for w in ("office chair", "desk lamp", "monitor", "coffee mug", "book shelf") for n in
             range(1, len(w) + 1)]
    queries = [c.lower() for c in categories] + typed
    for q in queries[:20]:  # warm up
        index.search(q)
    latencies = []
    for _ in range(3):
        for q in queries:
            t = time.perf_counter()
            index.search(q, limit=50)
            latencies.append((time.perf_counter() - t) * 1000)

    print(json.dumps({
        "benchmark": "corpus",
        "stanford_load_s": round(stanford_s, 3),
        "stanford_scenes": len(stanford.scenes),
        "stanford_objects": sum(len(s) for s in stanford.scenes),
        "ai2thor_load_s": round(ai2thor_s, 3),
        "ai2thor_scenes": len(ai2thor.scenes),
        "asset_build_stanford_per_model_s": round(stanford_build["per_model_s"], 3),
        "asset_build_stanford_models": stanford_build["built"],
        "asset_build_stanford_max_glb_mb": round(stanford_build["max_glb_bytes"] / 2**20, 3),
        "asset_build_procedural_per_model_s": round(demo_build["per_model_s"], 3),
        "asset_build_procedural_models": demo_build["built"],
        "search_models": len(index),
        "search_index_build_ms": round(index_s * 1000, 2),
        "search_queries": len(latencies),
        "search_p50_ms": round(statistics.median(latencies), 3),
        "search_p95_ms": round(percentile(latencies, 95), 3),
        "search_max_ms": round(max(latencies), 3),
    }, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
