"""How large an admin's participant page gets from what one participant stored: a participant of the demo study (in
process, SQLite) who searched with 2,000 '&' a time (the most a search text holds, each '&' five bytes escaped)
until their 32 MB quota was full; the page's bytes (the first page, where pages are), and the time to render it.
``--baseline DIR`` (a git worktree of an earlier revision) measures that revision in the same run.

Usage: .venv/bin/python benchmarks/bench_admin_page.py [--megabytes 32] [--baseline DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import checkout
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)

ROOT = Path(__file__).resolve().parents[1]
PASSWORD = "bench admin password"


def measure(megabytes: float) -> dict:
    """In this process: fill one participant's quota with searches, then render their page as the admin."""
    from demostudy import DEMOGRAPHICS, make_app
    from werkzeug.security import generate_password_hash

    from simulation.transport import FlaskTransport
    from simulation.walker import Walker

    with tempfile.TemporaryDirectory() as tmp:
        app = make_app(Path(tmp), ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
        client = app.test_client()
        page = Walker(FlaskTransport(client), "demo").to_first_trial({"pid": "filler"}, lambda _: DEMOGRAPHICS)
        boot, auth = page.boot, {"Authorization": f"Bearer {page.boot['token']}"}
        text, stored, seq = "&" * 2000, 0, 0
        while True:
            events = [{"seq": seq + i, "t": 1.7e12 + seq + i, "type": "search", "trial": boot["trial"]["index"],
                       "payload": {"text": text}} for i in range(200)]
            r = client.post("/api/events", headers=auth, json={"page_id": boot["page_id"], "events": events})
            if r.status_code != 200:
                break
            seq += 200
            stored += 200 * len(text)
            if stored >= megabytes * 2**20:
                break
        admin = app.test_client()
        login = admin.get("/admin/login").get_data(as_text=True)
        token = login.split('name="csrf_token" value="')[1].split('"')[0]
        admin.post("/admin/login", data={"csrf_token": token, "password": PASSWORD})
        t = time.perf_counter()
        shown = admin.get("/admin/demo/participants/1")
        took = time.perf_counter() - t
        return {"events": seq, "stored_mb": round(stored / 2**20, 1), "status": shown.status_code,
                "page_mb": round(len(shown.data) / 2**20, 2), "render_s": round(took, 2)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--megabytes", type=float, default=32.0)
    parser.add_argument("--baseline", help="another checkout to measure in the same run")
    parser.add_argument("--one", action="store_true", help=argparse.SUPPRESS)  # a subprocess's own measurement
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(args.megabytes)))
        return 0
    checkout.require(ROOT)

    def run(root: Path) -> dict:
        done = subprocess.run([sys.executable, __file__, "--one", "--megabytes", str(args.megabytes)],
                              env=checkout.env_for(root), capture_output=True, text=True, check=True)
        return json.loads(done.stdout.splitlines()[-1])

    out = {"benchmark": "admin_page", "this": run(ROOT)}
    if args.baseline:
        out["baseline"] = {"checkout": args.baseline, **run(Path(args.baseline))}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
