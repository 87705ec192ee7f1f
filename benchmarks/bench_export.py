"""Export benchmark: the admin's ``export.zip`` of a large study, its time and the server's peak memory.

A SQLite database of the demo study is filled with ``--participants`` participants whose events (each an insert
or a move of vocabulary 2, about 500 bytes of JSON payload) add up to ``--event-mb`` megabytes. Then, in a fresh
process per run, an app on that database serves ``GET /admin/demo/export.zip`` to a signed-in admin (the test
client, reading the body as it comes and dropping it). Measured per run: seconds to the last byte, the archive's
bytes, and the process's peak resident memory (``ru_maxrss``) above what it held just before the request (an
upper bound: a peak reached while the app started counts too). Reports the
median and range of ``--runs`` runs as JSON, for each size.

Run it on the code before a change and after (e.g. from a ``git worktree`` of the older commit, with that
checkout first on PYTHONPATH: :mod:`checkout`) to compare.
Usage: .venv/bin/python benchmarks/bench_export.py [--event-mb 33 330] [--participants 200] [--runs 3]
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import checkout
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from demostudy import make_app

ROOT = Path(__file__).resolve().parents[1]
PASSWORD = "bench-password"


def fill(folder: Path, participants: int, event_bytes: float) -> None:
    """A migrated database with ``participants`` consented participants of the demo study and their events."""
    from study_server.participants.assignment import arrive, assign

    app = make_app(folder)
    with app.app_context():
        study = app.extensions["studies"]["demo"].study
        ids = []
        for i in range(participants):
            p, _ = arrive(study, "link", f"bench-{i}")
            assign(study, p)
            ids.append(p.id)
    state = {"id": "o0", "model_id": "m", "category": "Chair", "size": [0.5, 0.9, 0.5],
             "transform": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.25, 0, 1.5, 1], "parent": "room",
             "surface_type": "up_interior", "attachment_face": "bottom", "contact_point": [0.25, 0.0, 1.5],
             "contact_normal": [0.0, 1.0, 0.0]}
    payload = json.dumps({"object": "o0", "distance": 0.01, "objects": [state]})
    per_participant = int(event_bytes / len(payload) / participants) + 1
    con = sqlite3.connect(folder / "study.sqlite3")
    with con:
        for pid in ids:
            con.executemany(
                "INSERT INTO events (participant_id, seq, page_id, type, trial, client_t, server_t, payload, "
                "vocabulary) VALUES (?, ?, 'bench', 'move_end', 0, ?, '2026-12-04 00:00:00', ?, 2)",
                ((pid, seq, 1.7e12 + seq, payload) for seq in range(per_participant)))
            con.execute("UPDATE participants SET acked_seq = ? WHERE id = ?", (per_participant - 1, pid))
    con.close()


def export_once(folder: Path) -> dict:
    """In this process: an app on ``folder``'s database serves the export to a signed-in admin (the test client,
    the body read as it comes and dropped). Seconds to the last byte, the archive's bytes, the resident memory
    just before the request and the peak above it (MB)."""
    import gc
    import os
    import re
    import resource

    from werkzeug.security import generate_password_hash

    app = make_app(folder, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    c = app.test_client()
    page = c.get("/admin/login").get_data(as_text=True)
    token = re.search(r'name="csrf_token" value="([^"]+)"', page).group(1)
    assert c.post("/admin/login", data={"csrf_token": token, "password": PASSWORD}).status_code == 302
    c.get("/admin/")
    gc.collect()
    resident = int(Path("/proc/self/statm").read_text().split()[1])  # pages
    before = resident * os.sysconf("SC_PAGE_SIZE") / 1024  # kB, as ru_maxrss
    start = time.perf_counter()
    r = c.get("/admin/demo/export.zip", buffered=False)
    size = 0
    for piece in r.response:
        size += len(piece)
    r.close()
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "zip_bytes": size, "rss_before_mb": before / 1024,
            "peak_mb": max(0, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--event-mb", type=float, nargs="+", default=[33, 330])
    parser.add_argument("--participants", type=int, default=200)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    checkout.require(ROOT)
    if args.one:
        print(json.dumps(export_once(Path(args.one))))
        return
    results = []
    for mb in args.event_mb:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            fill(folder, args.participants, mb * 1e6)
            runs = []
            for _ in range(args.runs):
                done = subprocess.run([sys.executable, __file__, "--one", str(folder)],
                                      capture_output=True, text=True, check=True)
                runs.append(json.loads(done.stdout.strip().splitlines()[-1]))

            def summary(key, runs=runs):
                values = [r[key] for r in runs]
                return {"median": statistics.median(values), "min": min(values), "max": max(values)}
            results.append({"event_mb": mb, "participants": args.participants, "runs": args.runs,
                            "seconds": summary("seconds"), "zip_bytes": summary("zip_bytes"),
                            "rss_before_mb": summary("rss_before_mb"), "peak_mb": summary("peak_mb")})
    print(json.dumps({"export": results, "measured_at": time.strftime("%Y-%m-%dT%H:%M:%S")}, indent=2))


if __name__ == "__main__":
    main()
