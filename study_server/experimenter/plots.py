"""What an experimenter watches while a study collects, drawn: participants over time by outcome, progress per
schedule row and per condition, trial time per condition and scene, flags over time.

Pilots (test runs and simulated participants: study_server.participants.pilots) are not drawn. Each plot is an SVG drawn
on the server with matplotlib (no script, no plotting library sent to the browser), and each has a table of the same
numbers (:func:`glance`) that the dashboard shows beside it, for readers of the page without images. Times are the
server's, UTC; trial time is from the trial page first shown to "done" (seconds).
"""

from __future__ import annotations

import io
import threading
from collections import Counter
from datetime import datetime

import numpy as np
from sqlalchemy import select

from ..base.extensions import db
from ..base.models import Participant, Trial
from ..studies.study_file import Study
from .decisions import progress

#: How a participant's status is drawn: outcome → the statuses it gathers.
OUTCOMES = {"completed": ("completed",), "in progress": ("in_progress",), "visiting": ("visiting",),
            "excluded": ("excluded",), "ended early": ("no_consent", "screened_out", "returned", "technical")}
COLOURS = {"completed": "#2e7d32", "in progress": "#1a4fb0", "visiting": "#9fb3d1", "excluded": "#b3261e",
           "ended early": "#8a6d00",
           "stale": "#7a7f87", "done": "#2e7d32", "open": "#1a4fb0", "unfinished": "#8a6d00", "raised": "#b3261e",
           "cleared": "#7a7f87"}
#: One hue per condition in the trial-time box plots, in the study's order: Okabe and Ito's colours, told apart
#: by readers with any common colour-vision deficiency (shades of one hue were read as one colour).
CONDITION_COLOURS = ("#E69F00", "#56B4E9", "#009E73", "#CC79A7")


def outcome(status: str, row: int = 0) -> str:
    """The outcome a participant is drawn as (one in progress without a row is a visitor: not consented)."""
    status = "visiting" if status == "in_progress" and row < 0 else status
    return next(name for name, statuses in OUTCOMES.items() if status in statuses)


def _arrivals(study: Study) -> list[tuple[datetime, str]]:
    rows = db.session.execute(select(Participant.created_at, Participant.status, Participant.row)
                              .where(Participant.study_id == study.id, Participant.pilot.is_(False))
                              .order_by(Participant.created_at))
    return [(at, outcome(status, row)) for at, status, row in rows if at is not None]  # None: unreadable


def _trial_times(study: Study) -> list[tuple[str, str, float]]:
    """(condition, scene, seconds) of every counted trial done."""
    rows = db.session.execute(select(Trial.condition, Trial.scene_id, Trial.started_at, Trial.done_at)
                              .join(Participant).where(Participant.study_id == study.id,
                                                       Participant.pilot.is_(False), Trial.kind == "trial",
                                                       Trial.done_at.is_not(None), Trial.started_at.is_not(None)))
    return [(c, s, (done - started).total_seconds()) for c, s, started, done in rows
            if started is not None and done is not None]  # None: unreadable


def _when(value) -> datetime | None:
    try:
        return datetime.fromisoformat(value)
    except (TypeError, ValueError):
        return None


def _flags(study: Study) -> list[tuple[datetime, datetime | None]]:
    """(raised at, cleared at or None) of every flag of the study's participants, by the time raised."""
    out = []
    for flags, in db.session.execute(select(Participant.flags).where(Participant.study_id == study.id,
                                                                     Participant.pilot.is_(False))):
        for f in flags or []:
            raised = _when(f.get("at"))
            if raised is not None:
                out.append((raised, _when(f.get("cleared_at"))))
    return sorted(out, key=lambda f: f[0])


def _flag_changes(flags: list[tuple[datetime, datetime | None]]) -> list[tuple[datetime, int, int]]:
    """(time, open flags then, cleared flags then) after each raise and each clearing, in time order."""
    changes = sorted([(raised, 1, 0) for raised, _ in flags]
                     + [(cleared, -1, 1) for _, cleared in flags if cleared is not None])
    out, still_open, cleared = [], 0, 0
    for at, opened, closed in changes:
        still_open, cleared = still_open + opened, cleared + closed
        out.append((at, still_open, cleared))
    return out


def glance(study: Study) -> dict:
    """The numbers the plots draw, as the dashboard's tables give them: arrivals per day by outcome, progress per
    row and condition (:func:`study_server.experimenter.decisions.progress`), trial seconds per condition and scene (n,
    median, quartiles), flags per day raised and cleared."""
    days: dict[str, Counter] = {}
    for at, name in _arrivals(study):
        days.setdefault(at.date().isoformat(), Counter())[name] += 1
    times = {}
    for c, s, sec in _trial_times(study):
        times.setdefault((c, s), []).append(sec)
    flag_days: dict[str, Counter] = {}
    for raised, cleared in _flags(study):
        flag_days.setdefault(raised.date().isoformat(), Counter())["raised"] += 1
        if cleared is not None:
            flag_days.setdefault(cleared.date().isoformat(), Counter())["cleared"] += 1
    order = {c.id: i for i, c in enumerate(study.conditions)}
    return {"arrivals": sorted(days.items()), "progress": progress(study),
            "trial_times": [{"condition": c, "scene": s, "n": len(v), "median": float(np.median(v)),
                             "q1": float(np.percentile(v, 25)), "q3": float(np.percentile(v, 75))}
                            for (c, s), v in sorted(times.items(), key=lambda kv: (order.get(kv[0][0], 99), kv[0]))],
            "flags": sorted(flag_days.items())}


# --- drawing ------------------------------------------------------------------------------------------------------
def _figure(width: float = 7.0, height: float = 3.2, columns: int = 1):
    """A figure (inches) and its axes, laid out by matplotlib's constrained layout."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    return fig, fig.subplots(1, columns)


#: matplotlib's settings are global: one drawing at a time sets and restores them (a threaded server).
_DRAWING = threading.Lock()


def _svg(fig) -> str:
    from matplotlib import rc_context

    out = io.StringIO()
    with _DRAWING, rc_context({"svg.fonttype": "none", "svg.hashsalt": "scenesuggest"}):  # text as text; stable ids
        fig.savefig(out, format="svg", metadata={"Date": None})
    return out.getvalue()


def _empty(ax, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="#5d6775")
    ax.set_axis_off()


def plot_participants(study: Study) -> str:
    """Participants who have arrived so far, cumulatively over time, stacked by outcome."""
    fig, ax = _figure()
    arrivals = _arrivals(study)
    if not arrivals:
        _empty(ax, "nobody has arrived yet")
        return _svg(fig)
    # one point per minute of arrivals at most: the image's size is bounded by the collection's length
    minutes = [at.replace(second=0, microsecond=0) for at, _ in arrivals]
    last = [i for i in range(len(minutes)) if i + 1 == len(minutes) or minutes[i + 1] != minutes[i]]
    times = [minutes[i] for i in last]
    stacks = [np.cumsum([name == o for _, name in arrivals])[last] for o in OUTCOMES]
    ax.stackplot(times, *stacks, labels=list(OUTCOMES), colors=[COLOURS[o] for o in OUTCOMES], step="post",
                 alpha=0.85)
    ax.set_ylabel("participants")
    ax.set_xlabel("arrival (UTC)")
    ax.legend(loc="upper left", fontsize="small", frameon=False)
    fig.autofmt_xdate()
    return _svg(fig)


def plot_progress(study: Study) -> str:
    """Participants per schedule row by state, and trials per condition by state, as stacked horizontal bars."""
    fig, (rows_ax, conditions_ax) = _figure(7.0, 1.4 + 0.3 * max(study.n_rows, len(study.conditions)), columns=2)
    prog = progress(study)
    _bars(rows_ax, [f"row {i}" for i in range(study.n_rows)], prog["rows"],
          ("completed", "in_progress", "stale", "excluded"), "participants per schedule row")
    _bars(conditions_ax, list(prog["conditions"]), list(prog["conditions"].values()), ("done", "open", "unfinished"),
          "trials per condition")
    return _svg(fig)


def _bars(ax, labels: list[str], counts: list[Counter], states: tuple[str, ...], title: str) -> None:
    left = np.zeros(len(labels))
    for state in states:
        values = np.array([c.get(state, 0) for c in counts], dtype=float)
        name = state.replace("_", " ")
        ax.barh(labels, values, left=left, label=name, color=COLOURS.get(name, COLOURS.get(state)))
        left += values
    ax.invert_yaxis()
    ax.set_title(title, fontsize="medium")
    ax.legend(fontsize="x-small", frameon=False, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=len(states))


def plot_trial_times(study: Study) -> str:
    """Box plots of trial seconds per scene, one box per condition side by side."""
    times = _trial_times(study)
    present = {scene for _, scene, _ in times}
    scenes = [s for s in study.scenes if s in present]  # in the study's order (not the practice's)
    conditions = [c.id for c in study.conditions]
    fig, ax = _figure(7.0, 3.4)
    if not times:
        _empty(ax, "no trial is done yet")
        return _svg(fig)
    width = 0.8 / len(conditions)
    grouped: dict[tuple[str, str], list[float]] = {}
    for c, scene, sec in times:
        grouped.setdefault((c, scene), []).append(sec)
    for j, c in enumerate(conditions):
        shade = CONDITION_COLOURS[j % len(CONDITION_COLOURS)]
        ax.plot([], [], "s", color=shade, label=c)
        where = [(i + (j - (len(conditions) - 1) / 2) * width, grouped[c, scene]) for i, scene in enumerate(scenes)
                 if (c, scene) in grouped]
        if not where:  # no trial of this condition done yet
            continue
        parts = ax.boxplot([d for _, d in where], positions=[x for x, _ in where], widths=width * 0.9,
                           patch_artist=True, manage_ticks=False, flierprops={"markersize": 3},
                           medianprops={"color": "#1d2430"})
        for box in parts["boxes"]:
            box.set(facecolor=shade, edgecolor="#1d2430")
    ax.set_xticks(range(len(scenes)), scenes, rotation=20, ha="right", fontsize="small", parse_math=False)
    ax.set_ylabel("seconds per trial")
    ax.legend(title="condition", fontsize="small", frameon=False)
    return _svg(fig)


def plot_flags(study: Study) -> str:
    """Flags over time: how many were open (raised, not yet cleared) and how many the experimenter had cleared."""
    fig, ax = _figure(7.0, 2.6)
    changes = _flag_changes(_flags(study))
    if not changes:
        _empty(ax, "no participant has been flagged")
        return _svg(fig)
    times = [at for at, _, _ in changes]
    ax.step(times, [n for _, n, _ in changes], where="post", color=COLOURS["raised"], label="open")
    ax.step(times, [n for _, _, n in changes], where="post", color=COLOURS["cleared"], label="cleared")
    ax.set_ylabel("flags")
    ax.legend(fontsize="small", frameon=False)
    fig.autofmt_xdate()
    return _svg(fig)


DRAW = {"participants": plot_participants, "progress": plot_progress, "trial-times": plot_trial_times,
        "flags": plot_flags}
