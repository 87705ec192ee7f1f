"""Measures from the event log: one row per trial, one per pick, one per participant.

Times are seconds on the participant's clock (``client_t_ms``), so network delays do not count. A trial runs
from its first ``trial_start`` to its last ``trial_done``; a trial without ``trial_done`` is incomplete and has
no measures. Practice trials (index −1) are left out.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from scenesuggest.picks import picks

from .load import StudyData

TRIAL_MEASURES = {
    "total_time": "seconds from the trial's start to “done”",
    "active_time": "total time less the time the tab was hidden",
    "rotation_time": "seconds spent turning objects (rotate start → end)",
    "translation_time": "seconds spent moving objects (move start → end)",
    "translation_distance": "metres objects were dragged",
    "n_text_queries": "keyword searches (a run of typing counts once)",
    "n_context_queries": "context queries (clicks asking for suggestions)",
    "n_queries": "model queries: keyword searches + context queries",
    "objects_inserted": "objects added (replacing a suggestion in place does not add one)",
    "n_picks": "models chosen from a list (inserts and in-place replacements)",
}


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


def event_dicts(events: pd.DataFrame) -> list[dict]:
    """Event rows as the shared functions of :mod:`scenesuggest` read them (``seq``, ``t``, ``type``, ``trial``,
    ``payload``), in the frame's order."""
    return [{"seq": s, "t": t, "type": k, "trial": None if tr != tr else int(tr), "payload": p}
            for s, t, k, tr, p in zip(events["seq"], events["client_t_ms"], events["type"], events["trial"],
                                      events["payload"], strict=True)]


PICK_COLUMNS = ["participant", "trial", "seq", "action", "model", "category", "source", "rank", "final"]


def picks_table(data: StudyData, trials: pd.DataFrame) -> pd.DataFrame:
    """One row per model placed from a list (:func:`scenesuggest.picks.picks`, the definition the export's
    ``picks.csv`` uses): its rank there (1-based), the list's source (``fixed`` list / ``search`` / ``context``),
    reciprocal rank, ``final`` (False when a later pick replaced it in place or it was undone; only final picks
    count for MRR and the rank distribution), and the trial's condition and scene."""
    ev = data.events.sort_values(["participant", "seq"])  # every event: undo, redo and page loads decide `final`
    rows = [{"participant": participant, "trial": int(p.trial), "seq": p.seq, "action": p.action,
             "model": p.model, "category": p.category, "source": p.source,
             "rank": float(p.rank) if p.rank else np.nan, "final": p.final}
            for participant, own in ev.groupby("participant", sort=False) for p in picks(event_dicts(own))
            if p.trial is not None]
    table = pd.DataFrame(rows, columns=PICK_COLUMNS)
    table["reciprocal_rank"] = 1.0 / table["rank"]
    design = trials.loc[trials["complete"], ["participant", "trial", "condition", "scene"]]
    return table.merge(design, on=["participant", "trial"], how="inner")


def participants_table(data: StudyData) -> pd.DataFrame:
    """One row per participant: status, and every survey answer as a column (``exit.enjoy_list``, …);
    numeric answers (Likert, age) become numbers."""
    people = data.participants[["participant", "status"]].copy()
    if not data.survey.empty:
        s = data.survey.assign(key=data.survey["survey"] + "." + data.survey["question"])
        wide = s.pivot_table(index="participant", columns="key", values="answer", aggfunc="last")
        for c in wide.columns:
            numeric = pd.to_numeric(wide[c], errors="coerce")
            if numeric.notna().sum() == wide[c].notna().sum():
                wide[c] = numeric
        people = people.merge(wide.reset_index(), on="participant", how="left")
    return people
