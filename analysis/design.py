"""Model matrices for mixed models, named the way R names them.

Fixed terms: a numeric column enters as itself; a text or categorical column (or ``factor(COL)`` for a numeric
one) enters as treatment dummies ``COLlevel`` against its first level — R's ``contr.treatment``. Levels are in
categorical order when the column is a pandas Categorical, otherwise sorted as R sorts factor levels.

Random terms: ``GROUP`` is a random intercept per level of GROUP; ``X|GROUP`` is a correlated random intercept
and slope of X per level of GROUP (lme4's ``(X | GROUP)``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import sparse

from .errors import AnalysisError

_FACTOR = re.compile(r"^factor\((.+)\)$")


@dataclass(frozen=True)
class RandomTerm:
    """One grouping factor: ``codes`` index ``levels`` per row; ``slope`` values per row when it has one."""

    group: str
    levels: tuple[str, ...]
    codes: np.ndarray
    slope_name: str | None = None
    slope: np.ndarray | None = None

    def z(self) -> sparse.csr_matrix:
        """Sparse random-effects columns: per level, an intercept (and the slope) column."""
        n, k = len(self.codes), len(self.levels)
        rows = np.arange(n)
        if self.slope is None:
            return sparse.csr_matrix((np.ones(n), (rows, self.codes)), shape=(n, k))
        cols = np.concatenate([2 * self.codes, 2 * self.codes + 1])
        vals = np.concatenate([np.ones(n), self.slope])
        return sparse.csr_matrix((vals, (np.concatenate([rows, rows]), cols)), shape=(n, 2 * k))


@dataclass(frozen=True)
class Design:
    """What a mixed model is fitted to; ``dropped`` rows had a missing value in a column the model uses;
    ``levels`` holds each categorical fixed term's levels, the reference first."""

    response: str
    y: np.ndarray
    X: np.ndarray
    fixed_names: tuple[str, ...]
    fixed_terms: tuple[str, ...]
    random: tuple[RandomTerm, ...]
    dropped: int = 0
    levels: tuple[tuple[str, tuple[str, ...]], ...] = ()

    @property
    def nobs(self) -> int:
        return len(self.y)

    def z(self) -> sparse.csr_matrix:
        return sparse.hstack([t.z() for t in self.random], format="csr")

    def without(self, term: str) -> Design:
        """The same design without one fixed term (the null model of a likelihood-ratio test)."""
        keep = [i for i, name in enumerate(self.fixed_names) if _term_of(name, self.fixed_terms) != term]
        return Design(self.response, self.y, self.X[:, keep], tuple(self.fixed_names[i] for i in keep),
                      tuple(t for t in self.fixed_terms if t != term), self.random, self.dropped,
                      tuple((t, lv) for t, lv in self.levels if t != term))

    def level_rows(self, term: str) -> list[tuple[str, np.ndarray]]:
        """(level, the indices of its rows) for every level of the categorical fixed ``term``, in order."""
        levels = dict(self.levels).get(term)
        if levels is None:
            raise AnalysisError(f"{term!r} is not a categorical fixed term of the model", "--fixed")
        dummies = self.X[:, [self.fixed_names.index(f"{term}{lv}") for lv in levels[1:]]]
        which = np.where(dummies.any(axis=1), dummies.argmax(axis=1) + 1, 0)
        return [(lv, np.flatnonzero(which == i)) for i, lv in enumerate(levels)]


def formula_of(design: Design) -> str:
    """lme4's formula for the design, as fits report it: ``y ~ condition + (1 | participant) + (1 | scene)``."""
    fixed = " + ".join(design.fixed_terms) or "1"
    random = " + ".join(f"({t.slope_name or 1} | {t.group})" for t in design.random)
    return f"{design.response} ~ {fixed} + {random}"


def _term_of(name: str, terms: tuple[str, ...]) -> str | None:
    if name == "(Intercept)":
        return None
    return max((t for t in terms if name.startswith(t)), key=len, default=None)


def levels_of(column: pd.Series) -> list:
    """Factor levels in R's order: categorical order, else sorted."""
    if isinstance(column.dtype, pd.CategoricalDtype):
        return [c for c in column.cat.categories if (column == c).any()]
    values = column.dropna().unique().tolist()
    try:
        return sorted(values)
    except TypeError:
        return sorted(values, key=str)


def _require(data: pd.DataFrame, column: str, role: str) -> None:
    if column not in data.columns:
        raise AnalysisError(f"no column {column!r} (columns: {', '.join(map(str, data.columns))})", role)


def _fixed_columns(data: pd.DataFrame, term: str, reference: str | None
                   ) -> tuple[list[str], list[np.ndarray], list | None]:
    """(column names, columns, the levels of a categorical term — None for a numeric one)."""
    m = _FACTOR.match(term)
    column = m.group(1) if m else term
    _require(data, column, "--fixed")
    values = data[column]
    categorical = bool(m) or not pd.api.types.is_numeric_dtype(values) or isinstance(values.dtype,
                                                                                      pd.CategoricalDtype)
    if not categorical:
        return [term], [values.to_numpy(float)], None
    levels = levels_of(values)
    if reference is not None:
        matches = [lv for lv in levels if str(lv) == str(reference)]
        if not matches:
            raise AnalysisError(f"reference level {reference!r} is not a level of {column!r} "
                                f"({', '.join(map(str, levels))})", "--reference")
        levels = matches + [lv for lv in levels if lv not in matches]
    if len(levels) < 2:
        raise AnalysisError(f"{column!r} has {len(levels)} level(s) with data; a fixed effect needs at least 2",
                            "--fixed")
    return ([f"{term}{lv}" for lv in levels[1:]],
            [(values == lv).to_numpy(float) for lv in levels[1:]], levels)


def _random_term(data: pd.DataFrame, spec: str) -> RandomTerm:
    slope_name, _, group = spec.rpartition("|")
    group, slope_name = group.strip(), slope_name.strip() or None
    _require(data, group, "--random")
    levels = levels_of(data[group])
    index = {lv: i for i, lv in enumerate(levels)}
    codes = data[group].map(index).to_numpy(int)
    slope = None
    if slope_name:
        _require(data, slope_name, "--random")
        slope = pd.to_numeric(data[slope_name], errors="coerce").to_numpy(float)
    return RandomTerm(group, tuple(map(str, levels)), codes, slope_name, slope)


def build_design(data: pd.DataFrame, response: str, fixed: list[str], random: list[str],
                 reference: str | None = None) -> Design:
    """Model matrices for ``response ~ fixed + (random)``; rows missing any used value are dropped."""
    if not random:
        raise AnalysisError("a mixed model needs at least one random term", "--random")
    _require(data, response, "--response")
    used = [response] + [(_FACTOR.match(t).group(1) if _FACTOR.match(t) else t) for t in fixed]
    used += [part.strip() for spec in random for part in spec.split("|")]
    for column in used:
        _require(data, column, "column")
    y_all = pd.to_numeric(data[response], errors="coerce")
    if y_all.isna().all():
        raise AnalysisError("has no numeric values", f"response {response!r}")
    complete = y_all.notna() & data[used[1:]].notna().all(axis=1) & np.isfinite(y_all.fillna(0))
    rows = data.loc[complete].reset_index(drop=True)
    if len(rows) < 3:
        raise AnalysisError(f"only {len(rows)} complete row(s)", f"response {response!r}")
    names, columns, levels = ["(Intercept)"], [np.ones(len(rows))], []
    for term in fixed:
        n, c, lv = _fixed_columns(rows, term, reference if term == fixed[0] else None)
        names += n
        columns += c
        if lv is not None:
            levels.append((term, tuple(map(str, lv))))
    X = np.column_stack(columns)
    if np.linalg.matrix_rank(X) < X.shape[1]:
        raise AnalysisError("the fixed effects are not estimable (a level is confounded with another term)",
                            "--fixed")
    terms = tuple(_random_term(rows, spec) for spec in random)
    return Design(response, y_all[complete].to_numpy(float), X, tuple(names), tuple(fixed), terms,
                  int((~complete).sum()), tuple(levels))
