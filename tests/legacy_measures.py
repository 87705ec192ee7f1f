"""The trial measures as the analysis package computed them one trial at a time in Python loops (before they were
vectorised): the oracle that tests/test_measures_vectorised.py holds the vectorised measures to, number for number."""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.load import StudyData
from analysis.measures import TRIAL_MEASURES


def total_time(events: pd.DataFrame) -> float:
    """Seconds from the first ``trial_start`` to the last ``trial_done`` (NaN if either is missing)."""
    starts = events.loc[events["type"] == "trial_start", "client_t_ms"]
    dones = events.loc[events["type"] == "trial_done", "client_t_ms"]
    if starts.empty or dones.empty:
        return float("nan")
    return float(dones.max() - starts.min()) / 1000.0


def hidden_time(events: pd.DataFrame, end_ms: float) -> float:
    """Seconds the tab was hidden (``visibility`` hidden → visible), up to ``end_ms``."""
    hidden_since, total = None, 0.0
    for t, payload in zip(events["client_t_ms"], events["payload"], strict=True):
        if payload.get("state") == "hidden" and hidden_since is None:
            hidden_since = t
        elif payload.get("state") == "visible" and hidden_since is not None:
            total += t - hidden_since
            hidden_since = None
    if hidden_since is not None:
        total += max(0.0, end_ms - hidden_since)
    return total / 1000.0


def interval_time(events: pd.DataFrame, start: str, end: str) -> float:
    """Seconds between each ``end`` event and the open ``start`` of the same object (rotation, translation)."""
    open_at: dict[str, float] = {}
    total = 0.0
    for kind, t, payload in zip(events["type"], events["client_t_ms"], events["payload"], strict=True):
        obj = payload.get("object")
        if kind == start:
            open_at[obj] = t
        elif kind == end and obj in open_at:
            total += t - open_at.pop(obj)
    return total / 1000.0


def text_queries(events: pd.DataFrame) -> int:
    """Keyword searches. The box logs its text as the participant types, so a run of searches whose texts
    extend or shorten one another counts once; a pick or a context query in between starts a new one."""
    count, last = 0, ""
    for kind, payload in zip(events["type"], events["payload"], strict=True):
        if kind == "search":
            text = str(payload.get("text", "")).strip().lower()
            if text and not (last and (text.startswith(last) or last.startswith(text))):
                count += 1
            last = text
        elif kind in ("insert", "replace", "context_query"):
            last = ""
    return count


def trial_measures(events: pd.DataFrame) -> dict[str, float]:
    """Every measure of one trial from its events (in ``seq`` order)."""
    kinds = events["type"]
    total = total_time(events)
    end = events.loc[kinds == "trial_done", "client_t_ms"].max() if (kinds == "trial_done").any() else np.nan
    visibility = events[kinds == "visibility"]
    n_text = text_queries(events)
    n_context = int((kinds == "context_query").sum())
    distances = [p.get("distance", 0.0) for p in events.loc[kinds == "move_end", "payload"]]
    return {
        "total_time": total,
        "active_time": total - hidden_time(visibility, end) if np.isfinite(total) else np.nan,
        "rotation_time": interval_time(events, "rotate_start", "rotate_end"),
        "translation_time": interval_time(events, "move_start", "move_end"),
        "translation_distance": float(np.sum(distances)),
        "n_text_queries": n_text,
        "n_context_queries": n_context,
        "n_queries": n_text + n_context,
        "objects_inserted": int((kinds == "insert").sum()),
        "n_picks": int(kinds.isin(["insert", "replace"]).sum()),
    }


def _events_by_trial(data: StudyData):
    ev = data.events.dropna(subset=["trial"]).sort_values(["participant", "seq"])
    return dict(iter(ev.groupby(["participant", ev["trial"].astype(int)], sort=False)))


def trials_table(data: StudyData) -> pd.DataFrame:
    """One row per scheduled (non-practice) trial with its design columns, measures and ``complete``."""
    trials = data.trials[data.trials["kind"] == "trial"].copy()
    groups = _events_by_trial(data)
    rows = []
    empty = pd.DataFrame({"type": pd.Series(dtype=str), "client_t_ms": pd.Series(dtype=float), "payload": []})
    for t in trials.itertuples(index=False):
        ev = groups.get((t.participant, int(t.trial)), empty)
        rows.append(trial_measures(ev))
    measures = pd.DataFrame(rows, index=trials.index, columns=list(TRIAL_MEASURES))
    out = pd.concat([trials, measures], axis=1)
    out["complete"] = np.isfinite(out["total_time"].astype(float))
    for name in TRIAL_MEASURES:
        out.loc[~out["complete"], name] = np.nan
    return out.reset_index(drop=True)
