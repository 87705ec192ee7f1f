"""A hanging engine and everyone else: the latency of a bystander's ``GET /api/session`` while two participants ask
for suggestions from an http engine that never answers (the external engine of tests/external_engine.py, path
``/hang``: headers, then nothing), ``timeout_ms = 2000``, on gunicorn with 2 sync workers as ``study serve`` runs
it (SQLite). The two ask one list after another, each at most every PACE_S seconds (within the list rate); the
bystander asks for its session every 50 ms. Also how long the askers waited for each list.

A checkout's own ``study serve`` is run, so ``--baseline DIR`` (a git worktree of an earlier revision) measures
that revision's server in the same run, for comparison. Median and range over ``--runs``.

Usage: .venv/bin/python benchmarks/bench_engine_hang.py [--seconds 12] [--runs 3] [--baseline DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import checkout
import numpy as np
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from serverproc import free_port, wait_for_port

ROOT = Path(__file__).resolve().parents[1]
DEMOGRAPHICS = {"age": "31", "experience_3d": "Never", "pointing_device": "Trackpad"}
#: An asker asks at most one list per PACE_S seconds: 2.5 per second, within the list rate (300 per 2 minutes).
PACE_S = 0.4


def external_engine(folder: Path) -> tuple[subprocess.Popen, str]:
    port_file = folder / "engine-port"
    proc = subprocess.Popen([sys.executable, str(ROOT / "tests" / "external_engine.py"), str(port_file)])
    deadline = time.monotonic() + 10
    while not port_file.exists() or not port_file.read_text():
        if time.monotonic() > deadline:
            raise SystemExit("the external engine did not start")
        time.sleep(0.02)
    return proc, f"http://127.0.0.1:{port_file.read_text()}/hang"


def study_with_engine(folder: Path, url: str) -> Path:
    """The demo study with both suggesting conditions served by the engine at ``url``."""
    from demostudy import DEMO_STUDY

    shutil.copytree(DEMO_STUDY.parent, folder / "study")
    path = folder / "study" / "study.toml"
    engine = f'engine = {{ name = "http", url = "{url}", timeout_ms = 2000 }}'
    text = path.read_text().replace('engine = { orientation = "learned" }', engine, 1)
    basic = text.index('id = "basic"')
    end = text.index("[[conditions]]", basic)
    path.write_text(text[:end] + engine + "\n\n" + text[end:])
    return path


def to_trial(base: str, pid: str):
    """A participant walked to their first trial over HTTP: (transport, boot data)."""
    from simulation.transport import HttpTransport
    from simulation.walker import Walker

    http = HttpTransport(base, retry_for=60.0)
    page = Walker(http, "demo").to_first_trial({"pid": pid}, lambda _: DEMOGRAPHICS)
    return http, page.boot


def measure(root: Path, seconds: float) -> dict:
    """One run against the checkout ``root``'s server: the bystander's and the askers' latencies (ms)."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        engine, url = external_engine(tmp)
        port = free_port()
        env = {**checkout.env_for(root), "SCENESUGGEST_INSTANCE": str(tmp / "instance"),
               "DATABASE_URL": f"sqlite:///{tmp / 'study.sqlite3'}",
               "SCENESUGGEST_STUDIES": str(study_with_engine(tmp, url)), "HOME": str(tmp / "home"),
               "SCENESUGGEST_HOME": os.environ.get("SCENESUGGEST_HOME", str(ROOT / "var")),  # the demo's priors
               "SCENESUGGEST_SECRET_KEY": "loopback-only-" + "x" * 32}
        server = subprocess.Popen([sys.executable, "-m", "scenesuggest.cli", "study", "serve", "--no-prepare",
                                   "--workers", "2", "--port", str(port)], env=env, cwd=tmp,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        try:
            wait_for_port(port, 120)
            base = f"http://127.0.0.1:{port}"
            walked = (to_trial(base, f"p{i}") for i in range(12))
            askers = [a for a in walked if a[1]["trial"]["condition"] != "none"][:2]  # those whose trial suggests
            bystander = to_trial(base, "bystander")
            asked: list[float] = []
            seen: list[float] = []
            stop = time.monotonic() + seconds

            statuses: list[int] = []

            def ask(http, boot):
                headers = {"Authorization": f"Bearer {boot['token']}"}
                start = http.get(f"/api/scenes/{boot['trial']['scene']}?which=start", headers=headers).json()
                body = {"trial": boot["trial"]["index"], "scene": {"objects": start["objects"]}, "parent": "room",
                        "point": [0.0, 0.0, 0.5], "normal": [0, 1, 0]}
                while time.monotonic() < stop:
                    t = time.perf_counter()
                    statuses.append(http.post("/api/suggest", json_body=body, headers=headers).status)
                    asked.append((time.perf_counter() - t) * 1000)
                    time.sleep(max(0.0, PACE_S - (time.perf_counter() - t)))

            threads = [threading.Thread(target=ask, args=a) for a in askers]
            for th in threads:
                th.start()
            http, boot = bystander
            headers = {"Authorization": f"Bearer {boot['token']}"}
            time.sleep(0.2)
            while time.monotonic() < stop:
                t = time.perf_counter()
                http.get("/api/session", headers=headers)
                seen.append((time.perf_counter() - t) * 1000)
                time.sleep(0.05)
            for th in threads:
                th.join()
        finally:
            os.killpg(server.pid, signal.SIGTERM)
            server.wait(timeout=30)
            engine.kill()
            engine.wait()
    if set(statuses) != {200}:
        raise SystemExit(f"the askers' suggestions were answered {sorted(set(statuses))}, not all 200")
    return {"session_p50_ms": float(np.percentile(seen, 50)), "session_p95_ms": float(np.percentile(seen, 95)),
            "session_max_ms": float(max(seen)), "session_requests": len(seen),
            "suggest_p50_ms": float(np.percentile(asked, 50)), "suggest_p95_ms": float(np.percentile(asked, 95)),
            "suggest_requests": len(asked)}


def summary(runs: list[dict]) -> dict:
    return {k: {"median": round(statistics.median(r[k] for r in runs), 1),
                "range": [round(min(r[k] for r in runs), 1), round(max(r[k] for r in runs), 1)]}
            for k in runs[0]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=12.0)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--baseline", help="another checkout whose server to measure in the same run")
    args = parser.parse_args()
    checkout.require(ROOT)
    out = {"benchmark": "engine_hang", "workers": 2, "timeout_ms": 2000, "seconds": args.seconds,
           "this": summary([measure(ROOT, args.seconds) for _ in range(args.runs)])}
    if args.baseline:
        out["baseline"] = {"checkout": args.baseline,
                           "measured": summary([measure(Path(args.baseline), args.seconds) for _ in range(args.runs)])}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
