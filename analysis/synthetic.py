"""A synthetic study export with known effects, in the export's exact format: for trying the report before a
study has run, for tests and for benchmarks. It is not a model of people (``scenesuggest study simulate``
drives the real server for that); its numbers are typed in here.

Design: conditions none / basic / full, six scenes in two periods of three, Williams-ordered condition blocks,
a practice trial; per trial 4–8 target objects, each found by keyword search (none) or a context query
(basic, full), moved and turned.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

CONDITIONS = ("none", "basic", "full")
PERIODS = (("S1", "S2", "S3"), ("S4", "S5", "S6"))
WILLIAMS = ((0, 1, 2), (1, 2, 0), (2, 0, 1), (0, 2, 1), (1, 0, 2), (2, 1, 0))
#: Per condition: P(chosen model at rank 1) of a geometric rank, seconds per object, P(turning needed).
EFFECTS = {"none": (0.35, 34.0, 0.9), "basic": (0.6, 26.0, 0.9), "full": (0.65, 22.0, 0.4)}
WORDS = ("sofa", "lamp", "table", "chair", "plant", "monitor", "book", "mug")


def _trial_events(rng, condition, speed, t0):
    p_top, per_object, p_turn = EFFECTS[condition]
    t = t0
    events = [("trial_start", t, {"condition": condition})]
    for k in range(int(rng.integers(4, 9))):
        t += rng.exponential(3.0) * 1000 * speed
        rank = int(min(rng.geometric(p_top), 40))
        if condition == "none" or rng.random() < 0.15:
            word = WORDS[k % len(WORDS)]
            for cut in (2, len(word)):
                events.append(("search", t, {"text": word[:cut]}))
                t += 400
            source = "search"
        else:
            events.append(("context_query", t, {"parent": "room", "point": [0, 0, 0], "normal": [0, 1, 0]}))
            source = "context"
        t += rng.exponential(per_object / 3) * 1000 * speed
        obj = f"o{k}"
        events.append(("insert", t, {"object": obj, "model": f"m{rank}", "category": "Thing", "rank": rank,
                                     "source": source}))
        move = rng.lognormal(np.log(per_object / 4), 0.4) * 1000 * speed
        events += [("move_start", t + 500, {"object": obj}),
                   ("move_end", t + 500 + move, {"object": obj, "distance": float(rng.gamma(2.0, 0.6))})]
        t += 500 + move
        if rng.random() < p_turn:
            turn = rng.lognormal(np.log(per_object / 5), 0.4) * 1000 * speed
            events += [("rotate_start", t + 300, {"object": obj}),
                       ("rotate_end", t + 300 + turn, {"object": obj, "angle": float(rng.normal(60, 40))})]
            t += 300 + turn
        if rng.random() < 0.03:
            away = rng.exponential(20.0) * 1000
            events += [("visibility", t + 100, {"state": "hidden"}), ("visibility", t + 100 + away,
                                                                      {"state": "visible"})]
            t += 100 + away
    t += 2000
    events.append(("trial_done", t, {"objects": 5}))
    return events, t


def write_export(out: str | Path, participants: int = 20, seed: int = 0, drop_last_trial: int = 0) -> Path:
    """Write ``participants`` synthetic participants (the last ``drop_last_trial`` of them leave before their
    final trial) as an export folder; returns the folder."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    people, trials, events, survey = [], [], [], []
    for p in range(1, participants + 1):
        row = (p - 1) % (len(WILLIAMS) * len(PERIODS))
        order, scenes = WILLIAMS[row % len(WILLIAMS)], PERIODS[row // len(WILLIAMS)]
        speed = float(rng.lognormal(0, 0.25))
        leaves = p > participants - drop_last_trial
        people.append({"participant": p, "study": "synthetic", "status": "returned" if leaves else "completed",
                       "row": row, "excluded_reason": ""})
        seq, t = 0, 1.7e12 + p * 1e7
        plan = [(-1, "practice", "full", "practice")] + [
            (3 * b + i, "trial", CONDITIONS[c], scenes[(i + b) % 3]) for b, c in enumerate(order) for i in range(3)]
        for position, (index, kind, condition, scene) in enumerate(plan):
            happened = not (leaves and position == len(plan) - 1)
            trials.append({"participant": p, "position": position, "trial": index, "kind": kind,
                           "condition": condition, "scene": scene, "period": row // len(WILLIAMS) + 1,
                           "block": max(0, index) // 3})
            if not happened:
                continue
            evs, t = _trial_events(rng, condition, speed, t + 5000)
            for kind_, at, payload in evs:
                events.append({"participant": p, "seq": seq, "page_id": f"pg{p}", "type": kind_, "trial": index,
                               "client_t_ms": repr(float(at)), "payload": json.dumps(payload)})
                seq += 1
        if not leaves:
            likert = {"enjoy_list": rng.integers(1, 4), "competent_list": rng.integers(2, 5),
                      "enjoy_suggestions": rng.integers(3, 6), "competent_suggestions": rng.integers(3, 6)}
            answers = {k: str(v) for k, v in likert.items()}
            answers["preference"] = str(rng.choice(["The model list", "Suggestions", "Suggestions, oriented"],
                                                   p=[0.15, 0.35, 0.5]))
            survey += [{"participant": p, "survey": "exit", "question": q, "answer": a} for q, a in answers.items()]
            survey.append({"participant": p, "survey": "demographics", "question": "age",
                           "answer": str(int(rng.integers(18, 70)))})
    import pandas as pd

    for name, rows in (("participants", people), ("trials", trials), ("events", events), ("survey", survey)):
        pd.DataFrame(rows).to_csv(out / f"{name}.csv", index=False)
    manifest = {"study": "synthetic", "title": "Synthetic study", "study_hash": "synthetic",
                "code_version": "synthetic", "exported_at": "", "design": {
                    "kind": "williams", "blocking": "condition", "rows": len(WILLIAMS) * len(PERIODS),
                    "conditions": list(CONDITIONS), "periods": [list(p) for p in PERIODS]}}
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return out
