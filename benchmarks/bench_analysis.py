"""Analysis benchmark: time and peak memory of the whole report (read export → measures → bootstrap → mixed
models → tables → figures → README) on synthetic exports of 20, 200 and 2,000 participants × 9 trials, as the CLI
runs it, each in a fresh process, three runs each (median and range).

Budgets on a 2-core machine: 200 × 9 ≤ 10 s; 2,000 × 9 (a large online study) ≤ 90 s and ≤ 2 GB peak memory.
``--baseline DIR`` also runs the same reports with the analysis package of another checkout (e.g. a git worktree
of an earlier revision), in the same run, for comparison: those reports run with that checkout first on
PYTHONPATH.

``--maximal`` times instead one maximal model fit of the same synthetic studies — total time (LMM, ML) and model
queries (Poisson GLMM, Laplace), each ``condition + (1 + condition | participant) + (1 + condition | scene)`` — and
lme4's fits of the same trials in the same run (Rscript; lme4's defaults, and for the LMM also run to convergence
with BOBYQA to rhoend = 1e-12 as tests/lme4_oracle.R does), with each fit's log-likelihood beside its time.

Usage: .venv/bin/python benchmarks/bench_analysis.py [--sizes 20,200,2000] [--runs 3] [--resamples 1000]
                                                      [--baseline DIR [--baseline-sizes 20,200]]
       .venv/bin/python benchmarks/bench_analysis.py --maximal [--sizes 200] [--runs 3]
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
import numpy as np

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


MAXIMAL = ["condition|participant", "condition|scene"]
LME4 = r"""
suppressMessages(library(lme4))
args <- commandArgs(trailingOnly = TRUE)
d <- read.csv(args[1], colClasses = c(participant = "character", scene = "character"))
d$condition <- factor(d$condition, levels = c("none", "basic", "full"))
runs <- as.integer(args[2])
converged <- lmerControl(optimizer = "bobyqa", optCtrl = list(rhoend = 1e-12, maxfun = 1e5))
random <- "(1 + condition | participant) + (1 + condition | scene)"
models <- list(
  lmm = function() lmer(as.formula(paste("total_time ~ condition +", random)), d, REML = FALSE),
  lmm_converged = function() lmer(as.formula(paste("total_time ~ condition +", random)), d, REML = FALSE,
                                  control = converged),
  glmm = function() glmer(as.formula(paste("n_queries ~ condition +", random)), d, family = poisson))
out <- lapply(models, function(f) {
  seconds <- numeric(runs)
  for (i in seq_len(runs)) seconds[i] <- system.time(m <- suppressWarnings(suppressMessages(f())))[["elapsed"]]
  list(seconds = seconds, logLik = as.numeric(logLik(m)), singular = isSingular(m),
       messages = as.list(m@optinfo$conv$lme4$messages))
})
cat(jsonlite::toJSON(out, auto_unbox = TRUE, digits = NA))
"""


def _summary(seconds) -> dict:
    seconds = sorted(np.atleast_1d(seconds).tolist())  # (one run comes from R's JSON as a number)
    return {"median_s": round(statistics.median(seconds), 3), "range_s": [round(seconds[0], 3),
                                                                          round(seconds[-1], 3)]}


def maximal(export: Path, runs: int, work: Path) -> dict:
    """Maximal model fits of ``export``'s completed trials, ``runs`` times each, here and in lme4."""
    import shutil

    import pandas as pd

    from analysis.design import build_design
    from analysis.load import read_export
    from analysis.mixed import fit
    from analysis.report import select

    trials, *_ , conditions, _ = select(read_export(export))
    trials = trials[trials["complete"]].copy()
    trials["condition"] = pd.Categorical(trials["condition"], conditions)
    out = {"trials": len(trials), "participants": int(trials["participant"].nunique()),
           "scenes": int(trials["scene"].nunique()), "here": {}}
    from analysis.errors import AnalysisError

    for name, measure, family in (("lmm", "total_time", "gaussian"), ("glmm", "n_queries", "poisson")):
        seconds = []
        try:
            for _ in range(runs):
                start = time.perf_counter()
                fitted = fit(build_design(trials, measure, ["condition"], MAXIMAL), family)
                seconds.append(time.perf_counter() - start)
        except AnalysisError as e:  # a model this package does not fit (yet): lme4's time stands alone
            out["here"][name] = {"not_fitted": e.message}
            continue
        out["here"][name] = {**_summary(seconds), "loglik": fitted.loglik, "singular": fitted.singular,
                             "messages": list(fitted.messages)}
    rscript = shutil.which("Rscript")
    if rscript is None:
        out["lme4"] = "Rscript is not installed (Debian: apt-get install r-cran-lme4 r-cran-jsonlite)"
        return out
    csv, script = work / "trials.csv", work / "lme4_maximal.R"
    trials[["participant", "scene", "condition", "total_time", "n_queries"]].to_csv(csv, index=False)
    script.write_text(LME4)
    ran = subprocess.run([rscript, "--vanilla", str(script), str(csv), str(runs)], capture_output=True, text=True)
    if ran.returncode != 0:
        raise SystemExit(f"lme4 failed:\n{ran.stderr[-2000:]}")
    out["lme4"] = {name: {**_summary(r["seconds"]), "loglik": r["logLik"], "singular": r["singular"],
                          "messages": r["messages"]} for name, r in json.loads(ran.stdout).items()}
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="20,200,2000", help="participants per study, comma-separated")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--resamples", type=int, default=1000)
    parser.add_argument("--baseline", help="another checkout whose analysis package to time in the same run")
    parser.add_argument("--baseline-sizes", default="20,200", help="the sizes to time the baseline at")
    parser.add_argument("--maximal", action="store_true", help="time maximal model fits here and in lme4")
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
    if args.maximal:
        result = {"benchmark": "analysis-maximal-models", "trials_per_participant": 9, "runs": args.runs,
                  "random": MAXIMAL, "studies": {}}
        with tempfile.TemporaryDirectory() as tmp:
            for n in sizes:
                export = write_export(Path(tmp) / f"export{n}", participants=n, seed=n)
                result["studies"][f"{n}x9"] = maximal(export, args.runs, Path(tmp))
        print(json.dumps(result))
        return 0
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
