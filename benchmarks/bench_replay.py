"""Replay benchmark: the size of the admin's replay document (``…/trials/N/replay.json``) for one long trial.

A participant of the demo study (a fresh SQLite database) places ``--objects`` objects in their first trial, then
moves them round and round until the trial's stored events reach ``--event-mb`` megabytes (each move an event of
vocabulary 2 carrying the moved object's state, sent through ``/api/events`` in batches as the page sends them).
Measured, ``--runs`` times: the bytes of the stored events (their payloads as JSON), the bytes of the replay
document as the admin gets it (``replay_document`` serialised as the endpoint serialises it), the seconds that
took, and the Python memory at the peak of building it (``tracemalloc``, a second build). Reports the median and
range as JSON.

Run it on the code before a change and after (e.g. from a ``git worktree`` of the older commit, with that
checkout first on PYTHONPATH: :mod:`checkout`) to compare.
Usage: .venv/bin/python benchmarks/bench_replay.py [--objects 40] [--event-mb 2.4] [--runs 3]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
import tracemalloc
from pathlib import Path

import checkout
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from demostudy import make_app, to_first_trial

ROOT = Path(__file__).resolve().parents[1]


def state(oid: str, x: float, z: float, model: str) -> dict:
    return {"id": oid, "model_id": model, "category": "Chair", "size": [0.5, 0.9, 0.5],
            "transform": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, 0, z, 1], "parent": "room",
            "surface_type": "up_interior", "attachment_face": "bottom", "contact_point": [x, 0.0, z],
            "contact_normal": [0.0, 1.0, 0.0]}


def one_run(objects: int, event_bytes: float) -> dict:
    from sqlalchemy import func, select

    from simulation.transport import FlaskTransport
    from study_server.base.extensions import db
    from study_server.base.models import Event, Participant, Trial
    from study_server.trials import replays

    with tempfile.TemporaryDirectory() as tmp:
        app = make_app(Path(tmp))
        c = app.test_client()
        b = to_first_trial(FlaskTransport(c), "bench-replay").boot
        auth = {"Authorization": f"Bearer {b['token']}"}
        trial = b["trial"]["index"]
        model = next(iter(app.extensions["studies"]["demo"].library))
        seq, batch, sent = 0, [], 0

        def flush():
            nonlocal batch
            r = c.post("/api/events", headers=auth, json={"page_id": b["page_id"], "vocabulary": 2,
                                                          "events": batch})
            assert r.status_code == 200, r.json
            batch = []

        def add(kind, **payload):
            nonlocal seq, sent
            e = {"seq": seq, "t": 1.7e12 + seq * 500.0, "type": kind, "trial": trial, "payload": payload}
            batch.append(e)
            sent += len(json.dumps(payload))
            seq += 1
            if len(batch) == 200:
                flush()

        for i in range(objects):
            s = state(f"o{i}", i * 0.1, 0.0, model)
            add("insert", object=s["id"], model=model, category="Chair", rank=1, source="fixed", objects=[s])
        while sent < event_bytes:
            i = seq % objects
            s = state(f"o{i}", i * 0.1, (seq % 97) * 0.01, model)
            add("move_end", object=s["id"], distance=0.01, objects=[s])
        if batch:
            flush()
        with app.app_context():
            stored = db.session.scalar(select(func.count()).select_from(Event))
            pid = db.session.scalar(select(Participant.id))
            t = db.session.scalar(select(Trial).where(Trial.participant_id == pid, Trial.index == trial))
            rt = app.extensions["studies"]["demo"]
            with app.test_request_context():
                start = time.perf_counter()
                body = app.json.dumps(replays.replay_document(rt, t))
                seconds = time.perf_counter() - start
                del body
                tracemalloc.start()  # again, counting the Python memory it takes at its peak
                body = app.json.dumps(replays.replay_document(rt, t))
                peak = tracemalloc.get_traced_memory()[1]
                tracemalloc.stop()
        return {"events": stored, "event_bytes": sent, "document_bytes": len(body.encode()), "seconds": seconds,
                "peak_mb": peak / 1e6, "format": "steps" if '"steps"' in body else "scenes"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, default=40)
    parser.add_argument("--event-mb", type=float, default=2.4)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    checkout.require(ROOT)
    runs = [one_run(args.objects, args.event_mb * 1e6) for _ in range(args.runs)]

    def summary(key):
        values = [r[key] for r in runs]
        return {"median": statistics.median(values), "min": min(values), "max": max(values)}
    print(json.dumps({"objects": args.objects, "event_mb": args.event_mb, "runs": args.runs,
                      "format": runs[0]["format"], "events": runs[0]["events"],
                      "event_bytes": runs[0]["event_bytes"], "document_bytes": summary("document_bytes"),
                      "seconds": summary("seconds"), "peak_mb": summary("peak_mb")},
                     indent=2))


if __name__ == "__main__":
    main()
