"""The vectorised trial measures give the numbers the one-trial-at-a-time Python loops gave (tests/legacy_measures.py),
bit for bit: on a synthetic study, on a study the bots took through the server, and on a hand-made log of every
odd thing a browser can send."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from demostudy import make_app
from legacy_measures import trials_table as legacy_trials_table

from analysis.load import StudyData, read_database, read_export
from analysis.measures import trials_table
from analysis.synthetic import write_export
from simulation.run import simulate


def same(data: StudyData) -> pd.DataFrame:
    new, old = trials_table(data), legacy_trials_table(data)
    pd.testing.assert_frame_equal(new.drop(columns=["language"], errors="ignore"), old, check_exact=True)
    return new


def test_a_synthetic_study(tmp_path):
    trials = same(read_export(write_export(tmp_path / "export", participants=40, seed=8, drop_last_trial=3)))
    assert (~trials["complete"]).sum() == 3 and (trials["active_time"] < trials["total_time"]).any()


def test_a_study_the_bots_took(tmp_path, demo_resources):
    app = make_app(tmp_path / "server")
    assert simulate(3, seed=2, study="demo", app=app)["completed"] == 3
    trials = same(read_database(app.config["SQLALCHEMY_DATABASE_URI"]))
    assert trials["complete"].all() and (trials["rotation_time"] > 0).any() and (trials["n_queries"] > 0).all()


def test_a_hand_made_log_of_odd_events():
    rows = []

    def log(participant, trial, kind, t, payload=None, seq=None):
        rows.append({"participant": participant, "seq": len(rows) if seq is None else seq, "type": kind,
                     "trial": trial, "client_t_ms": t, "payload": {} if payload is None else payload})

    # trial 0: repeated hides, a visible without a hide, moves of one object restarted, an end twice, objects
    # named by numbers and by nothing, searches that grow, shrink and change case
    for kind, t, payload in [
        ("trial_start", 1000.5, None), ("visibility", 1100, {"state": "visible"}),
        ("visibility", 1200, {"state": "hidden"}), ("visibility", 1250, {"state": "hidden"}),
        ("visibility", 1900.25, {"state": "visible"}), ("visibility", 2000, {"state": "prerender"}),
        ("move_start", 2100, {"object": "a"}), ("move_start", 2300, {"object": "a"}),
        ("move_end", 2900.1, {"object": "a", "distance": 0.1}), ("move_end", 3000, {"object": "a", "distance": 0.2}),
        ("rotate_start", 3100, {"object": 7}), ("rotate_end", 3300.7, {"object": "7"}),
        ("rotate_end", 3400, {"object": 7}), ("rotate_start", 3500, {}), ("rotate_end", 3650.3, {}),
        ("search", 3700, {"text": "Ch"}), ("search", 3800, {"text": " chair "}), ("search", 3900, {"text": "CHA"}),
        ("replace", 4000, {}), ("search", 4100, {"text": "chair"}), ("search", 4200, {"text": "lamp"}),
        ("search", 4300, {}), ("context_query", 4400, {}), ("insert", 4500, {"object": "b"}),
        ("move_end", 4600, {"object": "b"}),
        ("rotate_start", 4610, {"object": None}), ("rotate_end", 4620.5, {"object": None}),  # no id: one id
        ("rotate_start", 4630, {"object": float("nan")}), ("rotate_end", 4640, {"object": float("nan")}),  # never pair
        ("rotate_start", 4650, {"object": None}), ("rotate_end", 4660, {"object": float("nan")}),
        ("visibility", 4700, {"state": ["hidden"]}), ("visibility", 4710, {"state": None}),
        ("trial_done", 5000.125, None), ("trial_done", 5100, None)]:
        log(1, 0, kind, t, payload)
    # trial 1: hidden at done; trial 2: no done (incomplete); trial 3: no events at all; trial 5: not scheduled
    for kind, t, payload in [("trial_start", 10000, None), ("visibility", 12000, {"state": "hidden"}),
                             ("trial_done", 15000, None)]:
        log(1, 1, kind, t, payload)
    log(1, 2, "trial_start", 20000)
    log(1, 2, "visibility", 20500, {"state": "hidden"})
    log(1, 5, "trial_start", 30000)
    log(1, 5, "trial_done", 31000)
    # participant 2: events logged out of order (seq decides), a practice trial, a done before the start
    log(2, -1, "trial_start", 0)
    log(2, 0, "trial_done", 9000, seq=100)
    log(2, 0, "trial_start", 1000, seq=50)
    log(2, 0, "search", 2000, {"text": "mug"}, seq=60)
    log(2, 1, "trial_done", 500)
    log(2, 1, "trial_start", 700)
    events = pd.DataFrame(rows)
    trials = pd.DataFrame([{"participant": p, "position": i, "trial": tr, "kind": "practice" if tr < 0 else "trial",
                            "condition": "none", "scene": "S1"}
                           for p, scheduled in ((1, (0, 1, 2, 3)), (2, (-1, 0, 1))) for i, tr in enumerate(scheduled)])
    data = StudyData(participants=pd.DataFrame({"participant": [1, 2], "status": "completed"}), trials=trials,
                     events=events, survey=pd.DataFrame(columns=["participant", "survey", "question", "answer"]))
    table = same(data).set_index(["participant", "trial"])
    assert table.loc[(1, 0), "n_text_queries"] == 3 and table.loc[(1, 0), "translation_distance"] == pytest.approx(0.3)
    assert table.loc[(1, 0), "rotation_time"] == pytest.approx((3400 - 3100 + 3650.3 - 3500 + 4620.5 - 4610) / 1000)
    assert table.loc[(1, 0), "active_time"] == pytest.approx((5100 - 1000.5 - (1900.25 - 1200)) / 1000)  # the last done
    assert table.loc[(1, 1), "active_time"] == pytest.approx(2.0)  # hidden from 12 s until done at 15 s
    assert not table.loc[(1, 2), "complete"] and not table.loc[(1, 3), "complete"]
    assert table.loc[(2, 0), "total_time"] == pytest.approx(8.0) and table.loc[(2, 1), "total_time"] < 0
    assert np.isnan(table.loc[(1, 3), "n_queries"])


def test_an_object_id_that_is_a_list_pairs_by_its_text():
    """The loops failed on an id that is not hashable (a list); the group operations pair it by its repr."""
    from analysis.measures import trial_measures

    events = pd.DataFrame([{"type": k, "client_t_ms": t, "payload": p} for k, t, p in [
        ("trial_start", 0, {}), ("rotate_start", 100, {"object": ["c"]}), ("rotate_end", 350, {"object": ["c"]}),
        ("rotate_end", 400, {"object": ["d"]}), ("trial_done", 1000, {})]])
    measures = trial_measures(events)
    assert measures["rotation_time"] == pytest.approx(0.25) and measures["total_time"] == 1.0
    assert isinstance(measures["n_queries"], int)
