"""Measures from the event log: one row per trial, one per pick, one per participant.

Times are seconds on the participant's clock (``client_t_ms``), so network delays do not count. A trial runs
from its first ``trial_start`` to its last ``trial_done``; a trial without ``trial_done`` is incomplete and has
no measures. Practice trials (index −1) are left out.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from scenesuggest.contract.events import as_event
from scenesuggest.contract.picks import picks

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


def _payload_field(payloads, name: str, default=None) -> list:
    """``payload[name]`` of each event (payloads are dicts; anything else reads as empty)."""
    return [p.get(name, default) if isinstance(p, dict) else default for p in payloads]


class _Unmatched:
    """An object id that pairs with nothing, not even itself (as a NaN id never matched in a Python dict)."""


_NO_ID = object()  # a missing object id: one id, as ``None`` was one key


def _object_key(value):
    """A group key for an object id, pairing starts and ends as a dict keyed by the id would."""
    if value is None:
        return _NO_ID
    if isinstance(value, float) and value != value:
        return _Unmatched()
    return value if isinstance(value, (str, int, float, bool)) else repr(value)


def _object_array(values: list) -> np.ndarray:
    """A 1-D object array of ``values`` as they are (lists stay elements, not a second dimension)."""
    out = np.empty(len(values), dtype=object)
    out[:] = values
    return out


def _sequential_sums(keys: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """Per key (0..n-1), the sum of ``values`` added one at a time in their order, as a Python loop adds them (so
    the sums are the same to the last bit as the one-trial-at-a-time computation's)."""
    sums = [0.0] * n
    for k, v in zip(keys.tolist(), values.tolist(), strict=True):
        sums[k] += v
    return np.array(sums)


def _hidden_ms(kinds, t, payloads, key, end, n) -> np.ndarray:
    """Milliseconds each trial's tab was hidden: from a ``visibility`` hidden to the next visible (repeats
    ignored); a tab still hidden at the end counts until the trial's end."""
    vis = np.flatnonzero(kinds == "visibility")
    states = _object_array(_payload_field(payloads[vis], "state"))
    known = np.array([state in ("hidden", "visible") for state in states], dtype=bool)
    vis, states = vis[known], states[known]
    if not len(vis):
        return np.zeros(n)
    previous = np.r_[np.array(["visible"], dtype=object), states[:-1]]
    previous[np.r_[True, key[vis][1:] != key[vis][:-1]]] = "visible"  # each trial starts visible
    changed = states != previous  # so they alternate within a trial: hidden, visible, hidden, …
    changes, hidden = vis[changed], states[changed] == "hidden"
    ck, ct = key[changes], t[changes]
    durations = np.zeros(len(changes))
    closes = np.flatnonzero(~hidden)  # each follows the hidden of its own trial
    durations[closes] = ct[closes] - ct[closes - 1]
    trailing = np.r_[ck[1:] != ck[:-1], True] & hidden
    durations[trailing] = [max(0.0, e - h) for e, h in zip(end[ck[trailing]], ct[trailing], strict=True)]
    return _sequential_sums(ck, durations, n)


def measures_by_trial(events: pd.DataFrame, key: np.ndarray, n: int) -> pd.DataFrame:
    """Every measure of :data:`TRIAL_MEASURES` for ``n`` trials at once, by group operations.

    ``events`` (columns ``type``, ``client_t_ms``, ``payload``) are ordered by trial and, within a trial, by
    ``seq``; ``key[i]`` is the trial (0..n-1) that event i belongs to. A trial runs from its first
    ``trial_start`` to its last ``trial_done`` (NaN without either); the tab is hidden from a ``visibility``
    hidden to the next visible (repeats ignored; still hidden at the end counts until ``trial_done``); a
    rotation or move runs from an object's latest start to its end (an end without a start counts nothing); a run
    of searches whose texts extend or shorten one another is one keyword query, and a pick or a context query
    starts a new run."""
    kinds = events["type"].to_numpy(object)
    t = events["client_t_ms"].to_numpy(float)
    payloads = events["payload"].to_numpy(object)
    key = np.asarray(key, dtype=np.int64)
    frame = pd.DataFrame({"key": key, "t": t})

    def per_trial(mask: np.ndarray, how: str) -> np.ndarray:
        grouped = frame.loc[mask].groupby("key")["t"].agg(how)
        out = np.full(n, np.nan)
        out[grouped.index.to_numpy()] = grouped.to_numpy()
        return out

    def count(mask: np.ndarray) -> np.ndarray:
        return np.bincount(key[mask], minlength=n).astype(np.int64)

    start, end = per_trial(kinds == "trial_start", "min"), per_trial(kinds == "trial_done", "max")
    total = (end - start) / 1000.0

    hidden_ms = _hidden_ms(kinds, t, payloads, key, end, n)
    active = np.where(np.isfinite(total), total - hidden_ms / 1000.0, np.nan)

    def interval(start_kind: str, end_kind: str) -> np.ndarray:
        return _interval_seconds(kinds, t, payloads, key, n, start_kind, end_kind)

    n_text = _text_query_counts(kinds, payloads, key, n)
    n_context = count(kinds == "context_query")
    return pd.DataFrame({
        "total_time": total, "active_time": active,
        "rotation_time": interval("rotate_start", "rotate_end"),
        "translation_time": interval("move_start", "move_end"),
        "translation_distance": _distance(kinds, payloads, key, n), "n_text_queries": n_text,
        "n_context_queries": n_context,
        "n_queries": n_text + n_context, "objects_inserted": count(kinds == "insert"),
        "n_picks": count((kinds == "insert") | (kinds == "replace")),
    }, columns=list(TRIAL_MEASURES))


def _interval_seconds(kinds, t, payloads, key, n, start_kind: str, end_kind: str) -> np.ndarray:
    """Seconds per trial between each object's latest ``start_kind`` and its ``end_kind`` (an end without a start
    counts nothing)."""
    rows = np.flatnonzero((kinds == start_kind) | (kinds == end_kind))
    objects = [_object_key(o) for o in _payload_field(payloads[rows], "object")]
    sub = pd.DataFrame({"key": key[rows], "obj": pd.Series(objects, dtype=object), "t": t[rows],
                        "is_end": kinds[rows] == end_kind})
    by_object = sub.groupby(["key", "obj"], sort=False, dropna=False)
    opened = ~by_object["is_end"].shift(1, fill_value=True).to_numpy(bool)  # the previous one was a start
    before = by_object["t"].shift(1).to_numpy(float)
    pairs = sub["is_end"].to_numpy(bool) & opened
    return _sequential_sums(key[rows][pairs], t[rows][pairs] - before[pairs], n) / 1000.0


def _distance(kinds, payloads, key, n) -> np.ndarray:
    """Metres moved per trial: the sum of the ``move_end`` distances, in event order."""
    distance = np.zeros(n)
    moves = np.flatnonzero(kinds == "move_end")
    if len(moves):
        lists: dict[int, list] = {}
        for k, d in zip(key[moves], _payload_field(payloads[moves], "distance", 0.0), strict=True):
            lists.setdefault(int(k), []).append(d)
        for k, values in lists.items():
            distance[k] = float(np.sum(values))
    return distance


def _text_query_counts(kinds, payloads, key, n) -> np.ndarray:
    """Keyword searches per trial. The box logs its text as the participant types, so a run of searches whose
    texts extend or shorten one another counts once; a pick or a context query in between starts a new one."""
    rows = np.flatnonzero(np.isin(kinds, ["search", "insert", "replace", "context_query"]))
    texts = [str(p.get("text", "")).strip().lower() if kind == "search" and isinstance(p, dict) else
             ("" if kind == "search" else None) for kind, p in zip(kinds[rows], payloads[rows], strict=True)]
    counts = np.zeros(n, dtype=np.int64)
    last, last_key = "", None
    for k, text in zip(key[rows], texts, strict=True):
        if k != last_key:
            last, last_key = "", k
        if text is None:  # a pick or a context query
            last = ""
            continue
        if text and not (last and (text.startswith(last) or last.startswith(text))):
            counts[k] += 1
        last = text
    return counts


def trial_measures(events: pd.DataFrame) -> dict[str, float]:
    """Every measure of one trial from its events (in ``seq`` order)."""
    frame = measures_by_trial(events, np.zeros(len(events), dtype=np.int64), 1)
    return {name: frame[name].iloc[0].item() for name in TRIAL_MEASURES}


def text_queries(events: pd.DataFrame) -> int:
    """Keyword searches of one trial's events (see :func:`measures_by_trial`)."""
    return int(_text_query_counts(events["type"].to_numpy(object), events["payload"].to_numpy(object),
                                  np.zeros(len(events), dtype=np.int64), 1)[0])


def trials_table(data: StudyData) -> pd.DataFrame:
    """One row per scheduled (non-practice) trial with its design columns, measures and ``complete``."""
    trials = data.trials[data.trials["kind"] == "trial"].copy().reset_index(drop=True)
    ev = data.events.dropna(subset=["trial"])
    ev = ev.assign(trial=ev["trial"].astype(int)).sort_values(["participant", "trial", "seq"], kind="stable")
    wanted = pd.MultiIndex.from_arrays([trials["participant"], trials["trial"].astype(int)])
    unique = wanted.unique()  # a trial listed twice gets the same measures twice
    position = unique.get_indexer(pd.MultiIndex.from_arrays([ev["participant"], ev["trial"]]))
    ev, position = ev[position >= 0], position[position >= 0]
    measures = measures_by_trial(ev, position, len(unique)).iloc[unique.get_indexer(wanted)].reset_index(drop=True)
    out = pd.concat([trials, measures], axis=1)
    if "language" in data.participants:  # the language the participant's pages spoke: a grouping like any other
        spoke = data.participants.set_index("participant")["language"]
        out["language"] = out["participant"].map(spoke)
    out["complete"] = np.isfinite(out["total_time"].astype(float))
    for name in TRIAL_MEASURES:
        out.loc[~out["complete"], name] = np.nan
    return out


def event_dicts(events: pd.DataFrame) -> list[dict]:
    """Event rows as the shared functions of :mod:`scenesuggest` read them (``seq``, ``t``, ``type``, ``trial``,
    ``payload``), in the frame's order."""
    return [as_event(*row) for row in zip(events["seq"], events["client_t_ms"], events["type"], events["trial"],
                                          events["payload"], strict=True)]


PICK_COLUMNS = ["participant", "trial", "seq", "action", "model", "category", "source", "rank", "final"]


def picks_table(data: StudyData, trials: pd.DataFrame) -> pd.DataFrame:
    """One row per model placed from a list (:func:`scenesuggest.contract.picks.picks`, the definition the export's
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
    """One row per participant: status, whether a pilot, and every survey answer as a column
    (``exit.enjoy_list``, …); numeric answers (Likert, age) become numbers."""
    people = data.participants[["participant", "status", "pilot"]].copy()
    if not data.survey.empty:
        s = data.survey.assign(key=data.survey["survey"] + "." + data.survey["question"])
        wide = s.pivot_table(index="participant", columns="key", values="answer", aggfunc="last")
        for c in wide.columns:
            numeric = pd.to_numeric(wide[c], errors="coerce")
            if numeric.notna().sum() == wide[c].notna().sum():
                wide[c] = numeric
        people = people.merge(wide.reset_index(), on="participant", how="left")
    return people
