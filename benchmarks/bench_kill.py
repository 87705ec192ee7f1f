"""Kill test: simulated participants take the demo study over HTTP while the server (gunicorn, SQLite) is killed
with SIGKILL at random moments and restarted; afterwards every participant must have finished, every event
they generated must be stored exactly once, the Williams rows must stay balanced and the database must pass
its integrity check.

Prints one JSON object; exits non-zero when any of those fails. The test suite runs a short form.
Usage: .venv/bin/python benchmarks/bench_kill.py [--participants 20] [--kills 5] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import random
import signal
import sqlite3
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import checkout
import numpy as np
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from demostudy import rows_balance
from serverproc import DEMO_STUDY, StudyServer, demo_missing

from simulation.participant import Bot
from simulation.transport import FlowError, HttpTransport
from study_server.studies.study_file import load_study

ROOT = Path(__file__).resolve().parents[1]


def run(participants: int, kills: int, seed: int, workers: int) -> dict:
    rng = random.Random(seed)
    with tempfile.TemporaryDirectory() as tmp:
        database = Path(tmp) / "kill.sqlite3"
        server = StudyServer(Path(tmp) / "instance", f"sqlite:///{database}", workers)
        server.start().wait_ready()
        done = threading.Event()
        killed = []

        def killer():
            for _ in range(kills):
                if done.wait(rng.uniform(0.5, 2.5)):
                    return
                server.kill()
                killed.append(time.monotonic())
                time.sleep(rng.uniform(0.0, 0.5))
                server.start()

        def participant(i: int):
            bot = Bot(HttpTransport(server.base, retry_for=120.0), "demo", f"kill-{seed}-{i}",
                      np.random.default_rng([seed, i]))
            try:
                result = bot.run()
            except FlowError as e:
                return {"pid": bot.pid, "error": str(e), "events": bot.seq, "retries": bot.http.retries}
            return {"pid": bot.pid, "code": result.code, "events": bot.seq, "retries": bot.http.retries}

        started = time.perf_counter()
        thread = threading.Thread(target=killer, daemon=True)
        thread.start()
        with ThreadPoolExecutor(max_workers=participants) as pool:
            results = list(pool.map(participant, range(participants)))
        done.set()
        thread.join()
        # every kill must have happened while participants were still working; keep killing until it did
        while len(killed) < kills:
            server.kill()
            killed.append(time.monotonic())
            server.start()
        server.wait_ready()
        server.kill(signal.SIGTERM)
        elapsed = time.perf_counter() - started
        with sqlite3.connect(database) as con:
            stored, distinct = con.execute("SELECT COUNT(*), COUNT(DISTINCT CAST(participant_id AS TEXT) || '-' || "
                                           "CAST(seq AS TEXT)) FROM events").fetchone()
            rows, balanced = rows_balance((r for (r,) in con.execute(
                "SELECT row FROM participants WHERE status = 'completed'")), load_study(DEMO_STUDY))
            people = con.execute("SELECT COUNT(*), SUM(status = 'completed') FROM participants").fetchone()
            integrity = con.execute("PRAGMA integrity_check").fetchone()[0]
    generated = sum(r["events"] for r in results)
    completed = sum(1 for r in results if r.get("code"))
    return {"benchmark": "kill", "kills": len(killed), "participants": participants, "completed": completed,
            "participants_in_db": people[0], "completed_in_db": int(people[1] or 0), "events_generated": generated,
            "events_stored": stored, "duplicates": stored - distinct, "rows_balanced": balanced,
            "rows": rows, "integrity": integrity,
            "retries": sum(r["retries"] for r in results), "elapsed_s": round(elapsed, 1),
            "errors": [r["error"] for r in results if "error" in r]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--participants", type=int, default=20)
    parser.add_argument("--kills", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    checkout.require(ROOT)
    if demo_missing():
        print(json.dumps({"benchmark": "kill", "error": demo_missing()}))
        return 1
    out = run(args.participants, args.kills, args.seed, args.workers)
    print(json.dumps(out))
    ok = (out["completed"] == out["participants"] == out["completed_in_db"] == out["participants_in_db"]
          and out["events_stored"] == out["events_generated"] and out["duplicates"] == 0 and out["rows_balanced"]
          and out["integrity"] == "ok" and out["kills"] >= args.kills)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
