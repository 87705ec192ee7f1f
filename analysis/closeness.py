"""How close each trial's scene came to its target: the final score of every trial (``trials.csv``, scored by the
server with :mod:`scenesuggest.contract.scoring` when the trial was done and stored with it; trials done before the
server stored scores are scored at export) and the score over the trial's elapsed time, rebuilt from its events
(:mod:`scenesuggest.contract.replay`) and scored the same way, so one sees how fast each interface gets a scene
right, not only when participants stop.

Events of vocabulary 1 (written before the events carried object states) cannot be rebuilt: their trials have a
final score but no score over time, which the report notes.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from scenesuggest.contract.replay import ReplayUnavailable, apply, start_scene
from scenesuggest.contract.scoring import closeness

from .bootstrap import bootstrap_by
from .load import StudyData
from .measures import event_dicts
from .tables import Table

#: column → (label, digits): what the table shows, when the data has it.
CLOSENESS = {"score": ("Score (0–1)", 2), "matched": ("Objects matched", 2), "missing": ("Missing", 2),
             "extra": ("Extra", 2), "position_error_m": ("Position error (m)", 3),
             "orientation_error_deg": ("Orientation error (°)", 1)}
#: The test of condition, like the times': (column, label, digits, family, table).
SCORE_TEST = ("score", "Score (0–1)", 2, "gaussian", "trials")
STEP_S = 5.0


def closeness_table(trials: pd.DataFrame, conditions: list[str], resamples: int = 1000, seed: int = 0,
                    unit: str = "trial") -> Table | None:
    """Means per condition with 95% bootstrap intervals of every closeness column the data has (None: none)."""
    done = trials[trials["complete"]]
    columns = [c for c in CLOSENESS if c in done.columns and done[c].notna().any()]
    if not columns:
        return None
    if "score" in columns:  # trials without a final scene have no score, nor a row here
        done = done[done["score"].notna()]
    stats = {c: bootstrap_by(done.dropna(subset=[c]), c, "condition", conditions, unit, resamples, seed)
             for c in columns}
    rows, data = [], []
    for cond in conditions:
        n = int((done["condition"] == cond).sum())
        rows.append([cond, str(n)] + [stats[c][cond].text(CLOSENESS[c][1]) for c in columns])
        record = {"condition": cond, "trials": n}
        for c in columns:
            iv = stats[c][cond]
            record |= {f"{c}_mean": iv.mean, f"{c}_low": iv.low, f"{c}_high": iv.high, f"{c}_n": iv.n}
        data.append(record)
    what = "participants" if unit == "participant" else "trials"
    caption = (f"How close each completed trial's final scene came to its target (the score and its parts; see "
               f"the data dictionary for the formula): means per condition with 95% percentile bootstrap "
               f"intervals from {resamples} resamples of {what}, seed {seed}.")
    return Table("closeness", "How close to the target", caption,
                 ["Condition", "Trials"] + [CLOSENESS[c][0] for c in columns], rows, data)


def score_over_time(data: StudyData, trials: pd.DataFrame, step_s: float = STEP_S) -> tuple[pd.DataFrame, list[str]]:
    """The score of every completed trial every ``step_s`` seconds of its elapsed time (from ``trial_start``),
    the final score carried on after "done" up to the longest trial; and notes on what could not be rebuilt.
    Columns: participant, trial, condition, elapsed_s, score."""
    scenes = data.scenes.get("scenes", {})
    parents, periods = data.scenes.get("taxonomy", {}), data.scenes.get("symmetry_deg", {})
    columns = ["participant", "trial", "condition", "elapsed_s", "score"]
    if not scenes:
        return pd.DataFrame(columns=columns), ["score over time: the data has no scenes.json (an export made by "
                                               "an earlier version, or a database): nothing to rebuild trials from"]
    done = trials[trials["complete"]]
    events = data.events.dropna(subset=["trial"]).sort_values(["participant", "seq"])
    groups = dict(iter(events.groupby(["participant", events["trial"].astype(int)], sort=False)))
    curves, unavailable = [], 0
    for t in done.itertuples(index=False):
        own = groups.get((t.participant, int(t.trial)))
        scene = scenes.get(t.scene)
        if own is None or scene is None:
            continue
        try:
            curves.append((t, _curve(event_dicts(own), scene, parents.get, lambda m: periods.get(m, 360.0))))
        except ReplayUnavailable:
            unavailable += 1
    notes = [f"score over time: {unavailable} completed trial(s) have events without object states (event "
             "vocabulary 1) and are left out; their final scores are in the table"] if unavailable else []
    if not curves:
        return pd.DataFrame(columns=columns), notes
    horizon = max(float(t.total_time) for t, _ in curves)
    grid = np.arange(0.0, horizon + step_s, step_s)
    rows = []
    for t, (times, scores) in curves:
        at = np.maximum.accumulate(np.asarray(times))  # a clock that stepped back after a reload
        sampled = np.asarray(scores)[np.searchsorted(at, grid, side="right") - 1]
        rows += [(t.participant, int(t.trial), t.condition, float(g), float(s)) for g, s in zip(grid, sampled,
                                                                                             strict=True)]
    return pd.DataFrame(rows, columns=columns), notes


def _curve(events: list[dict], scene: dict, parent_of, period_of) -> tuple[list[float], list[float]]:
    """(elapsed seconds, score) at the trial's start and after every event that changed the scene."""
    start_ms = next((e["t"] for e in events if e["type"] == "trial_start"), events[0]["t"])
    start_ids = [o["id"] for o in scene["start"]]
    current = start_scene(scene["start"])
    times, scores = [0.0], [closeness(current.values(), scene["target"], start_ids, parent_of, period_of).score]
    for e in events:
        after = apply(current, e)
        if after is not current:
            current = after
            times.append(max(0.0, (e["t"] - start_ms) / 1000.0))
            scores.append(closeness(current.values(), scene["target"], start_ids, parent_of, period_of).score)
    return times, scores
