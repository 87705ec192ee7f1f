"""Power of the likelihood-ratio tests by simulation: repeated studies drawn from a pilot.

Each simulated study of N participants draws N participants with replacement from a pilot (a real pilot
study, or simulated participants from ``scenesuggest study simulate``), keeping each participant's trials and
picks together (so their own speed, order and scenes come along), relabels the draws as distinct participants,
and runs every test of the report. Power is the share of studies whose test rejects at ``alpha``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from .design import build_design
from .errors import AnalysisError
from .mixed import compare
from .tables import MEASURES, random_terms


def _draw(frame: pd.DataFrame, chosen: np.ndarray) -> pd.DataFrame:
    groups = dict(iter(frame.groupby("participant")))
    parts = [groups[p].assign(participant=f"d{i}") for i, p in enumerate(chosen) if p in groups]
    return pd.concat(parts, ignore_index=True) if parts else frame.iloc[:0]


def p_values(trials: pd.DataFrame, picks: pd.DataFrame, conditions: list[str],
             measures: list[str] | None = None) -> dict[str, float]:
    """The LR-test p-value of condition for every Table 1 measure (or those of ``measures``; NaN where a model
    cannot be fitted)."""
    out = {}
    for measure, _, _, family, table in MEASURES:
        if measures is not None and measure not in measures:
            continue
        frame = picks if table == "picks" else trials
        frame = frame[frame["condition"].isin(conditions)].copy()
        frame["condition"] = pd.Categorical(frame["condition"], conditions)
        try:
            out[measure] = compare(build_design(frame, measure, ["condition"], random_terms(frame)), "condition",
                                   family).lrt.p
        except (AnalysisError, np.linalg.LinAlgError, ValueError, FloatingPointError):
            out[measure] = float("nan")
    return out


def power(trials: pd.DataFrame, picks: pd.DataFrame, conditions: list[str], sizes: list[int], studies: int,
          seed: int = 0, alpha: float = 0.05, progress: Callable[[str], None] = lambda label: None,
          measures: list[str] | None = None) -> dict:
    """``{N: {measure: power}}`` from ``studies`` simulated studies per size (seeded), for every Table 1 measure
    or those of ``measures``."""
    trials = trials[trials["complete"]]
    pilot = sorted(trials["participant"].unique(), key=str)
    if len(pilot) < 2:
        raise AnalysisError(f"the pilot has {len(pilot)} participant(s) with completed trials; need at least 2")
    if any(n < 2 for n in sizes) or studies < 1:
        raise AnalysisError("sizes must be ≥ 2 participants and --studies ≥ 1", "--participants")
    rng = np.random.default_rng(seed)
    table: dict[int, dict[str, float]] = {}
    for n in sizes:
        rejections: dict[str, list[bool]] = {m: [] for m, *_ in MEASURES if measures is None or m in measures}
        for k in range(studies):
            chosen = rng.choice(pilot, size=n, replace=True)
            for measure, p in p_values(_draw(trials, chosen), _draw(picks, chosen), conditions,
                                       measures).items():
                if np.isfinite(p):
                    rejections[measure].append(p < alpha)
            progress(f"N = {n}: study {k + 1}/{studies}")
        table[n] = {m: (float(np.mean(r)) if r else float("nan")) for m, r in rejections.items()}
    return {"alpha": alpha, "studies": studies, "seed": seed, "pilot_participants": len(pilot),
            "power": {str(n): v for n, v in table.items()}}
