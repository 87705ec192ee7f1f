"""Participant-path benchmark: the server's CPU for one participant's whole way through the demo study's pages —
entry link, device check, consent (assignment), demographics, instructions, each condition's instructions where
they come, every trial page and its "done" (one small event batch each), the exit survey and the end page — in
process (the Flask test client, SQLite), as the request count and the CPU milliseconds per participant, several
runs of a fresh database each in a fresh process (median and range).

What is timed is the process's CPU while the walker goes through the pages, the walker's own small work included
(the same in every checkout). ``--baseline DIR`` runs the same walk with the packages of another checkout (a git
worktree of an earlier revision), in the same run, for comparison.

Usage: .venv/bin/python benchmarks/bench_pages.py [--participants 30] [--runs 3] [--baseline DIR]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import checkout
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)

ROOT = Path(__file__).resolve().parents[1]
DEMOGRAPHICS = {"age": "31", "experience_3d": "Never", "pointing_device": "Trackpad"}


class Counting:
    """A transport that counts the requests it sends."""

    def __init__(self, inner):
        self.inner, self.requests = inner, 0

    def get(self, *args, **kwargs):
        self.requests += 1
        return self.inner.get(*args, **kwargs)

    def post(self, *args, **kwargs):
        self.requests += 1
        return self.inner.post(*args, **kwargs)


def walk_one(app, pid: str) -> int:
    """One participant through the whole study (a small batch of events and "done" per trial); its requests."""
    from demostudy import play_empty_trial

    from simulation.transport import FlaskTransport
    from simulation.walker import Walker

    http = Counting(FlaskTransport(app.test_client()))
    seq = 0

    def trial(boot: dict) -> bool:
        nonlocal seq
        seq = play_empty_trial(http, boot, seq, boot["page_id"], 1.7e12, 20000)
        return True

    def answers(page) -> dict:
        if page.step == "exit":
            return {**{q: values[0] for q, values in page.radios.items()}, "last_seq": str(seq - 1), "attempt": "0"}
        return DEMOGRAPHICS

    walker = Walker(http, "demo")
    end = walker.walk(answers, trial, page=walker.enter({"pid": pid}))
    assert end.step == "done" and end.code, end.step
    return http.requests


def one_run(root: Path, participants: int, work: Path) -> dict:
    """In this process: ``participants`` walked through the demo study on a fresh database with the packages of
    ``root`` (first on this process's PYTHONPATH)."""
    checkout.require(root, ("study_server", "simulation"))
    from demostudy import make_app

    app = make_app(work)
    requests, start = 0, time.process_time()
    for i in range(participants):
        requests += walk_one(app, f"bench-{i}")
    cpu = time.process_time() - start
    return {"cpu_ms_per_participant": 1000 * cpu / participants, "requests_per_participant": requests / participants}


def measure(root: Path, participants: int, runs: int) -> dict:
    results = []
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as tmp:
            env = {**checkout.env_for(root), "SCENESUGGEST_HOME": str(ROOT / "var")}  # the demo's library, priors
            out = subprocess.run([sys.executable, __file__, "--one", "--root", str(root), "--participants",
                                  str(participants), "--work", tmp], capture_output=True, text=True, env=env,
                                 cwd=ROOT)
        if out.returncode != 0:
            raise SystemExit(f"the walk with {root} failed:\n{out.stderr[-3000:]}")
        results.append(json.loads(out.stdout.splitlines()[-1]))
    cpu = sorted(r["cpu_ms_per_participant"] for r in results)
    return {"cpu_ms_per_participant_median": round(statistics.median(cpu), 1),
            "cpu_ms_per_participant_range": [round(cpu[0], 1), round(cpu[-1], 1)],
            "requests_per_participant": results[0]["requests_per_participant"]}


parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--participants", type=int, default=30)
parser.add_argument("--runs", type=int, default=3)
parser.add_argument("--baseline", help="another checkout whose packages to walk with in the same run")
parser.add_argument("--one", action="store_true", help=argparse.SUPPRESS)
parser.add_argument("--root", default=str(ROOT), help=argparse.SUPPRESS)
parser.add_argument("--work", help=argparse.SUPPRESS)


def main() -> int:
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_run(Path(args.root), args.participants, Path(args.work))))
        return 0
    out = {"benchmark": "pages", "participants": args.participants, "runs": args.runs,
           "walk": measure(ROOT, args.participants, args.runs)}
    if args.baseline:
        out["baseline"] = {"checkout": args.baseline,
                           "walk": measure(Path(args.baseline).resolve(), args.participants, args.runs)}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
