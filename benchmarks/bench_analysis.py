"""Analysis benchmark: time for the whole report (read export → measures → bootstrap → mixed models → tables
→ figures → README) on synthetic exports of 20 × 9 and 200 × 9 trials, as the CLI runs it.

Prints one JSON object. Budgets on a 2-core machine: 20 × 9 ≤ 10 s, 200 × 9 ≤ 60 s.
Usage: .venv/bin/python benchmarks/bench_analysis.py [--resamples 1000]
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from analysis.load import read_export  # noqa: E402
from analysis.report import build_report  # noqa: E402
from analysis.synthetic import write_export  # noqa: E402


def report_seconds(participants: int, resamples: int, work: Path) -> tuple[float, dict]:
    export = write_export(work / f"export{participants}", participants=participants, seed=participants)
    stages: dict[str, float] = {}
    start = time.perf_counter()
    last = [start, "read"]

    def progress(label: str) -> None:
        now = time.perf_counter()
        stages[last[1]] = stages.get(last[1], 0.0) + now - last[0]
        last[:] = [now, label.split(" of ")[0]]

    summary = build_report(read_export(export), work / f"report{participants}", resamples=resamples,
                           progress=progress)
    progress("end")
    assert not any("not modelled" in n for n in summary["notes"]), summary["notes"]
    return time.perf_counter() - start, {k: round(v, 2) for k, v in stages.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--resamples", type=int, default=1000)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        small, small_stages = report_seconds(20, args.resamples, Path(tmp))
        large, large_stages = report_seconds(200, args.resamples, Path(tmp))
    print(json.dumps({"benchmark": "analysis", "report_20x9_s": round(small, 2), "report_200x9_s": round(large, 2),
                      "stages_20x9_s": small_stages, "stages_200x9_s": large_stages, "resamples": args.resamples,
                      "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
