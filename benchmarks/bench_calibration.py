"""Calibration benchmark: what one evaluation of each fold's fit costs on the SceneSuggest replication (a rehearsal
of 40 bots' trials of the fold's conditions in process, the study's own engine answering the suggestion clicks),
with one worker process and with two, and so what each fold's calibration costs at its number of evaluations; and
a 20-participant simulated replication (every bot through the whole study, into a fresh SQLite database). Several
runs, median and range; the one-worker rehearsal is the baseline the two-worker one is compared with, in the same
run.

Needs the prepared replication (``make replication`` or ``experiments/scenesuggest-2015/prepare.py``) and its
``none`` calibration for the simulated run.

Usage: .venv/bin/python benchmarks/bench_calibration.py [--runs 3] [--participants 40] [--no-simulate]
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
sys.path.insert(0, str(ROOT))
REPLICATION = ROOT / "experiments" / "scenesuggest-2015"
#: The folds `make replication` fits, with their evaluations.
FOLDS = {"none": 500, "none,basic": 350, "none,full": 350, "basic,full": 350}


def summary(values: list[float]) -> dict:
    return {"median": round(statistics.median(values), 3), "min": round(min(values), 3),
            "max": round(max(values), 3)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--participants", type=int, default=40)
    parser.add_argument("--no-simulate", action="store_true")
    args = parser.parse_args()
    if not (ROOT / "var" / "experiments" / "scenesuggest-2015" / "priors.npz").is_file():
        print("the replication is not prepared: run `make replication` first", file=sys.stderr)
        return 2
    tmp = Path(tempfile.mkdtemp(prefix="bench-calibration-"))
    os.environ.update({"SCENESUGGEST_STUDIES": str(REPLICATION / "study.toml"),
                       "SCENESUGGEST_INSTANCE": str(tmp / "instance"),
                       "DATABASE_URL": f"sqlite:///{tmp / 'calibrate.sqlite3'}"})
    from simulation.calibrate import Rehearsal, read
    from simulation.cli import _app

    app, study_id = _app(None)
    calibrated = read(REPLICATION / "calibration" / "none.json")
    out = {"participants": args.participants, "runs": args.runs, "cpus": len(os.sched_getaffinity(0)),
           "folds": {}}
    for fold, evaluations in FOLDS.items():
        per_workers = {}
        for workers in (1, 2):
            rehearsal = Rehearsal(app, study_id, args.participants, 0, tuple(fold.split(",")), workers=workers)
            rehearsal.measure(calibrated)  # warm: engine, meshes' symmetry, worker processes
            seconds = []
            for _ in range(args.runs):
                started = time.perf_counter()
                rehearsal.measure(calibrated)
                seconds.append(time.perf_counter() - started)
            rehearsal.close()
            per_workers[workers] = seconds
        two = summary(per_workers[2])
        out["folds"][fold] = {"evaluation_s_1_worker": summary(per_workers[1]), "evaluation_s_2_workers": two,
                              "speedup": round(statistics.median(per_workers[1]) / two["median"], 2),
                              "evaluations": evaluations,
                              "projected_fit_minutes": round(evaluations * two["median"] / 60, 1)}
        print(json.dumps({fold: out["folds"][fold]}), file=sys.stderr, flush=True)
    if not args.no_simulate:
        from simulation.run import simulate
        from study_server import create_app, upgrade_database

        seconds = []
        for k in range(args.runs):
            started = time.perf_counter()
            run_app = create_app({"SQLALCHEMY_DATABASE_URI": f"sqlite:///{tmp / f'study-{k}.sqlite3'}",
                                  "INSTANCE_PATH": str(tmp / f"instance-{k}")})
            upgrade_database(run_app)
            result = simulate(20, 0, study=study_id, app=run_app, human=calibrated)
            seconds.append(time.perf_counter() - started)
            if result["completed"] != 20:
                print(f"only {result['completed']} of 20 completed", file=sys.stderr)
                return 1
        out["simulated_replication_20_participants_s"] = summary(seconds)
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
