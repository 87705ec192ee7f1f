"""Percentile bootstrap confidence intervals of means, resampling trials (the paper) or participants.

Rows are grouped into resampling units (clusters): a unit's rows move together, so the mean of resampled
rows is Σ sums / Σ counts over the drawn units. For trial-level data with ``unit="trial"`` every row is its
own unit and this is the ordinary bootstrap of a mean; for picks it pools the picks of the drawn trials.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .errors import AnalysisError

UNITS = ("trial", "participant")


@dataclass(frozen=True)
class Interval:
    mean: float
    low: float
    high: float
    n: int

    def to_dict(self) -> dict:
        return {"mean": self.mean, "low": self.low, "high": self.high, "n": self.n}

    def text(self, digits: int = 1) -> str:
        if not np.isfinite(self.mean):
            return "no data"
        return f"{self.mean:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


def unit_columns(frame: pd.DataFrame, unit: str) -> list[str]:
    """The columns that identify a resampling unit in ``frame``."""
    if unit not in UNITS:
        raise AnalysisError(f"unknown unit {unit!r} (choose trial or participant)", "--unit")
    if unit == "participant":
        if "participant" not in frame.columns:
            raise AnalysisError("resampling participants needs a 'participant' column", "--unit")
        return ["participant"]
    return ["participant", "trial"] if {"participant", "trial"} <= set(frame.columns) else []


def bootstrap_mean(values: np.ndarray, clusters: np.ndarray | None, rng: np.random.Generator,
                   resamples: int = 1000, level: float = 0.95) -> Interval:
    """Mean of ``values`` and its percentile interval from ``resamples`` draws of the clusters."""
    values = np.asarray(values, dtype=float)
    keep = np.isfinite(values)
    values = values[keep]
    if len(values) == 0:
        return Interval(float("nan"), float("nan"), float("nan"), 0)
    if clusters is None:
        sums, counts = values, np.ones(len(values))
    else:
        codes, index = np.unique(np.asarray(clusters)[keep], return_inverse=True)
        sums = np.bincount(index, values, minlength=len(codes))
        counts = np.bincount(index, minlength=len(codes)).astype(float)
    k = len(sums)
    draws = rng.integers(0, k, size=(resamples, k))
    means = sums[draws].sum(axis=1) / counts[draws].sum(axis=1)
    alpha = (1 - level) / 2
    low, high = np.quantile(means, [alpha, 1 - alpha])
    return Interval(float(values.mean()), float(low), float(high), int(len(values)))


def bootstrap_by(frame: pd.DataFrame, value: str, by: str, levels: list | None = None, unit: str = "trial",
                 resamples: int = 1000, seed: int = 0, empty_ok: bool = False) -> dict[str, Interval]:
    """Per level of ``by`` (in ``levels`` order; levels without data get an empty interval), the mean of
    ``value`` with its 95% interval. One seeded generator serves the levels in order, so results repeat.
    A ``value`` without any number is an error, unless ``empty_ok`` (a report's measure that a pilot has no
    data for yet): then every level's interval is empty."""
    for column in (value, by):
        if column not in frame.columns:
            raise AnalysisError(f"no column {column!r} (columns: {', '.join(map(str, frame.columns))})",
                                "--value" if column == value else "--by")
    if resamples < 10:
        raise AnalysisError("must be at least 10", "--resamples")
    ids = unit_columns(frame, unit)
    numeric = pd.to_numeric(frame[value], errors="coerce")
    if numeric.notna().sum() == 0 and not empty_ok:
        raise AnalysisError("has no numeric values", f"--value {value}")
    rng = np.random.default_rng(seed)
    levels = levels if levels is not None else sorted(frame[by].dropna().unique().tolist(), key=str)
    out = {}
    for lv in levels:
        rows = frame[by] == lv
        clusters = None
        if ids:
            clusters = frame.loc[rows, ids].astype(str).agg("\x1f".join, axis=1).to_numpy()
        out[str(lv)] = bootstrap_mean(numeric[rows].to_numpy(), clusters, rng, resamples)
    return out
