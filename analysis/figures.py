"""The report's figures (PNG and SVG): total time by condition per target scene (the paper's box plots), the
distribution of chosen ranks, per-participant learning curves over trial position, and how close the scenes came
to their targets over the trials' elapsed time.

Figures are built on :class:`matplotlib.figure.Figure` directly (no pyplot state, no display needed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from .tables import RANK_BINS

COLOURS = ["#7f7f7f", "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b"]


def _save(fig: Figure, out: Path, name: str) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / f"{name}.png", out / f"{name}.svg"]
    fig.savefig(paths[0], dpi=150, bbox_inches="tight")
    fig.savefig(paths[1], bbox_inches="tight")
    return paths


def time_by_scene(trials: pd.DataFrame, conditions: list[str], out: Path) -> list[Path]:
    """Box plots of total time (s) by condition, one panel per target scene."""
    done = trials[trials["complete"]]
    scenes = sorted(done["scene"].unique(), key=str)
    cols = min(3, max(1, len(scenes)))
    rows = max(1, int(np.ceil(len(scenes) / cols)))
    fig = Figure(figsize=(3.2 * cols, 2.8 * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False, sharey=True)
    for ax, scene in zip(axes.flat, scenes, strict=False):
        here = done[done["scene"] == scene]
        data = [here.loc[here["condition"] == c, "total_time"].to_numpy() for c in conditions]
        box = ax.boxplot(data, patch_artist=True, widths=0.6, medianprops={"color": "black"})
        ax.set_xticks(range(1, len(conditions) + 1), conditions)
        for patch, colour in zip(box["boxes"], COLOURS, strict=False):
            patch.set_facecolor(colour)
            patch.set_alpha(0.6)
        ax.set_title(str(scene), fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    for ax in axes.flat[len(scenes):]:
        ax.set_visible(False)
    for ax in axes[:, 0]:
        ax.set_ylabel("total time (s)")
    fig.suptitle("Total time by condition for each target scene")
    return _save(fig, out, "time_by_scene")


def rank_distribution(picks: pd.DataFrame, conditions: list[str], out: Path) -> list[Path]:
    """Share of picks at rank 1, 2, 3 and 4+ per condition (grouped bars)."""
    fig = Figure(figsize=(6, 3.5), layout="constrained")
    ax = fig.subplots()
    ranked = picks.dropna(subset=["rank"])
    width = 0.8 / max(1, len(conditions))
    x = np.arange(len(RANK_BINS))
    for i, c in enumerate(conditions):
        r = ranked.loc[ranked["condition"] == c, "rank"]
        counts = np.array([(r == 1).sum(), (r == 2).sum(), (r == 3).sum(), (r >= 4).sum()], dtype=float)
        shares = counts / counts.sum() if counts.sum() else counts
        ax.bar(x + (i - (len(conditions) - 1) / 2) * width, shares, width, label=f"{c} (n = {int(counts.sum())})",
               color=COLOURS[i % len(COLOURS)])
    ax.set_xticks(x, [f"rank {b}" for b in RANK_BINS])
    ax.set_ylabel("share of picks")
    ax.set_ylim(0, 1)
    ax.legend(frameon=False)
    ax.set_title("Rank of the chosen model in its list")
    return _save(fig, out, "rank_distribution")


def learning_curves(trials: pd.DataFrame, conditions: list[str], out: Path) -> list[Path]:
    """Total time against trial position: one thin line per participant, the mean per position and condition
    as markers (order effects are what the Latin square balances)."""
    done = trials[trials["complete"]].copy()
    done["order"] = done.groupby("participant")["position"].rank(method="first").astype(int)
    fig = Figure(figsize=(6.5, 3.8), layout="constrained")
    ax = fig.subplots()
    for _, rows in done.sort_values("order").groupby("participant"):
        ax.plot(rows["order"], rows["total_time"], color="0.6", alpha=0.35, linewidth=0.8)
    for i, c in enumerate(conditions):
        means = done[done["condition"] == c].groupby("order")["total_time"].mean()
        ax.plot(means.index, means.values, "o", color=COLOURS[i % len(COLOURS)], label=f"{c} (mean)")
    overall = done.groupby("order")["total_time"].mean()
    ax.plot(overall.index, overall.values, color="black", linewidth=2, label="all (mean)")
    ax.set_xlabel("trial position")
    ax.set_ylabel("total time (s)")
    ax.set_xticks(sorted(done["order"].unique()))
    ax.legend(frameon=False, fontsize=8)
    ax.set_title("Learning curves")
    return _save(fig, out, "learning_curves")


def closeness_over_time(scores: pd.DataFrame, conditions: list[str], out: Path) -> list[Path]:
    """Median score (how close the scene is to its target, 0..1) over elapsed seconds per condition, with the
    interquartile band; a finished trial keeps its final score."""
    fig = Figure(figsize=(6.5, 3.8), layout="constrained")
    ax = fig.subplots()
    for i, c in enumerate(conditions):
        here = scores[scores["condition"] == c]
        if here.empty:
            continue
        q = here.groupby("elapsed_s")["score"].quantile([0.25, 0.5, 0.75]).unstack()
        n = here.groupby(["participant", "trial"]).ngroups
        colour = COLOURS[i % len(COLOURS)]
        ax.plot(q.index, q[0.5], color=colour, label=f"{c} (n = {n} trials)")
        ax.fill_between(q.index, q[0.25], q[0.75], color=colour, alpha=0.15, linewidth=0)
    ax.set_xlabel("seconds since the trial started")
    ax.set_ylabel("score (median, interquartile band)")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(frameon=False, loc="lower right")
    ax.set_title("How close to the target, over time")
    return _save(fig, out, "closeness_over_time")
