"""Analysis benchmark: time and peak memory of the whole report (read export → measures → bootstrap → mixed
models → tables → figures → README) on synthetic exports of 20, 200 and 2,000 participants × 9 trials, as the CLI
runs it, each in a fresh process, three runs each (median and range).

Budgets on a 2-core machine: 200 × 9 ≤ 10 s; 2,000 × 9 (a large online study) ≤ 90 s and ≤ 2 GB peak memory.
``--baseline DIR`` also runs the same reports with the analysis package of another checkout (e.g. a git worktree
of an earlier revision), in the same run, for comparison: those reports run with that checkout first on
PYTHONPATH.

Usage: .venv/bin/python benchmarks/bench_analysis.py [--sizes 20,200,2000] [--runs 3] [--resamples 1000]
                                                      [--baseline DIR [--baseline-sizes 20,200]]
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import checkout

ROOT = Path(__file__).resolve().parents[1]


def one_report(root: Path, export: Path, resamples: int, work: Path) -> dict:
    """In this process: the report of ``export`` with the analysis package of ``root`` (the checkout first on
    this process's PYTHONPATH), timed by stage."""
    checkout.require(root, ("analysis",))
    from analysis.load import read_export
    from analysis.report import build_report

    stages: dict[str, float] = {}
    start = time.perf_counter()
    last = [start, "read"]

    def progress(label: str) -> None:
        now = time.perf_counter()
        stages[last[1]] = stages.get(last[1], 0.0) + now - last[0]
        last[:] = [now, label.split(" of ")[0]]

    summary = build_report(read_export(export), work / "report", resamples=resamples, progress=progress)
    progress("end")
    seconds = time.perf_counter() - start
    assert not any("not modelled" in n for n in summary["notes"]), summary["notes"]
    return {"seconds": seconds, "stages_s": {k: round(v, 2) for k, v in stages.items()},
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def measure(root: Path, export: Path, runs: int, resamples: int) -> dict:
    """``runs`` reports of ``export``, each in a fresh process: median and range of the time, the stages of the
    median run, the largest peak memory."""
    results = []
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as tmp:
            out = subprocess.run([sys.executable, __file__, "--one", str(export), "--root", str(root),
                                  "--resamples", str(resamples), "--work", tmp], capture_output=True, text=True,
                                 env=checkout.env_for(root))
        if out.returncode != 0:
            raise SystemExit(f"report of {export} failed:\n{out.stderr[-3000:]}")
        results.append(json.loads(out.stdout))
    times = sorted(r["seconds"] for r in results)
    median = statistics.median(times)
    middle = min(results, key=lambda r: abs(r["seconds"] - median))
    return {"median_s": round(median, 2), "range_s": [round(times[0], 2), round(times[-1], 2)],
            "stages_of_median_run_s": middle["stages_s"],
            "peak_rss_mb": round(max(r["peak_rss_mb"] for r in results), 1)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="20,200,2000", help="participants per study, comma-separated")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--resamples", type=int, default=1000)
    parser.add_argument("--baseline", help="another checkout whose analysis package to time in the same run")
    parser.add_argument("--baseline-sizes", default="20,200", help="the sizes to time the baseline at")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    parser.add_argument("--root", default=str(ROOT), help=argparse.SUPPRESS)
    parser.add_argument("--work", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_report(Path(args.root), Path(args.one), args.resamples, Path(args.work))))
        return 0
    checkout.require(ROOT, ("analysis",))
    from analysis.synthetic import write_export

    sizes = [int(n) for n in args.sizes.split(",")]
    baseline_sizes = [int(n) for n in args.baseline_sizes.split(",")] if args.baseline else []
    out = {"benchmark": "analysis", "trials_per_participant": 9, "resamples": args.resamples, "runs": args.runs,
           "reports": {}}
    if args.baseline:
        out["baseline"] = {"checkout": args.baseline, "reports": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for n in sorted(set(sizes) | set(baseline_sizes)):
            export = write_export(Path(tmp) / f"export{n}", participants=n, seed=n)  # the same data for both
            if n in sizes:
                out["reports"][f"{n}x9"] = measure(ROOT, export, args.runs, args.resamples)
            if n in baseline_sizes:
                out["baseline"]["reports"][f"{n}x9"] = measure(Path(args.baseline).resolve(), export, args.runs,
                                                               args.resamples)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
