"""Model matrices for mixed models, named the way R names them.

Fixed terms: a numeric column enters as itself; a text or categorical column (or ``factor(COL)`` for a numeric
one) enters as treatment dummies ``COLlevel`` against its first level — R's ``contr.treatment``. Levels are in
categorical order when the column is a pandas Categorical, otherwise sorted as R sorts factor levels.

Random terms: ``GROUP`` is a random intercept per level of GROUP; ``X|GROUP`` a random intercept and slope of X
per level of GROUP, correlated (lme4's ``(1 + X | GROUP)``); X is a numeric column, or a factor, whose slope is its
treatment dummies (the same coding as the fixed term). Several slopes: ``X + W|GROUP``; no intercept: ``0 + X|GROUP``.
``X||GROUP`` is the same with every correlation left out: the intercept and each column of X (each dummy of a factor)
get a variance of their own (afex's ``expand_re = TRUE``; lme4's own ``(1 + X || GROUP)`` keeps a factor's dummies
correlated: in lme4 such a term is ``(1 | GROUP) + (0 + dummy(X, "b") | GROUP) + …``). Without an intercept the first
factor is coded by every level, as R codes it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import sparse

from .errors import AnalysisError

_FACTOR = re.compile(r"^factor\((.+)\)$")
#: The most random effects one term may have per level of its group (a covariance of 55 parameters)
MAX_EFFECTS = 10


@dataclass(frozen=True)
class RandomTerm:
    """One random-effects term: per level of ``group`` (``codes`` index ``levels`` per row), effects on the model
    matrix columns ``names`` (``values``: one row per observation, one column per name; ``(Intercept)`` a column of
    ones), with a full covariance between them (lme4's ``(… | group)``). Uncorrelated effects are several terms on
    the same group."""

    group: str
    levels: tuple[str, ...]
    codes: np.ndarray
    names: tuple[str, ...] = ("(Intercept)",)
    values: np.ndarray | None = None  # None: the intercept alone

    @property
    def width(self) -> int:
        """Effects per level (the size of the term's covariance matrix)."""
        return len(self.names)

    def columns(self) -> np.ndarray:
        """The term's model-matrix columns, n × width."""
        return np.ones((len(self.codes), 1)) if self.values is None else self.values

    def z(self) -> sparse.csr_matrix:
        """Sparse random-effects columns, level-major as lme4 lays them out: per level, one column per name."""
        n, k = len(self.codes), self.width
        rows = np.repeat(np.arange(n), k)
        cols = (self.codes[:, None] * k + np.arange(k)).ravel()
        return sparse.csr_matrix((self.columns().ravel(), (rows, cols)), shape=(n, k * len(self.levels)))

    def label(self) -> str:
        """lme4's spelling: ``(1 | participant)``, ``(1 + conditionbasic + conditionfull | participant)``."""
        names = ["1" if n == "(Intercept)" else n for n in self.names]
        if "1" not in names:
            names.insert(0, "0")
        return f"({' + '.join(names)} | {self.group})"


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
    random = " + ".join(t.label() for t in design.random)
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


def _fixed_columns(data: pd.DataFrame, term: str, reference: str | None, role: str = "--fixed"
                   ) -> tuple[list[str], list[np.ndarray], list | None]:
    """(column names, columns, the levels of a categorical term — None for a numeric one)."""
    m = _FACTOR.match(term)
    column = m.group(1) if m else term
    _require(data, column, role)
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
        raise AnalysisError(f"{column!r} has {len(levels)} level(s) with data; "
                            f"{'a fixed effect' if role == '--fixed' else 'a random slope'} needs at least 2", role)
    return ([f"{term}{lv}" for lv in levels[1:]],
            [(values == lv).to_numpy(float) for lv in levels[1:]], levels)


def _shown(spec: str, limit: int = 80) -> str:
    """A ``--random`` spec as an error message quotes it: its first ``limit`` characters."""
    return repr(spec if len(spec) <= limit else spec[:limit] + "…")


def _parse(spec: str) -> tuple[list[str], str, bool]:
    """A ``--random`` spec's parts: (what is left of the bar, split at +), the group, and whether it is ``||``."""
    uncorrelated = "||" in spec
    left, _, group = spec.replace("||", "|").rpartition("|")
    group, left = group.strip(), left.strip()
    if re.search(r"[()]", re.sub(r"factor\([^()]*\)", "", spec)):  # parentheses only as factor(COLUMN)
        raise AnalysisError(f"{_shown(spec)}: write a random term without lme4's parentheses, as GROUP, X|GROUP or "
                            "X||GROUP", "--random")
    if not group or "|" in left:
        raise AnalysisError(f"{_shown(spec)} is not a random term (GROUP, X|GROUP or X||GROUP)", "--random")
    parts = [p.strip() for p in left.split("+")] if left else []
    if any(not p for p in parts):
        raise AnalysisError(f"{_shown(spec)} has an empty term", "--random")
    return parts, group, uncorrelated


def _random_terms(data: pd.DataFrame, spec: str, references: dict[str, str | None]) -> list[RandomTerm]:
    """The terms of one ``--random`` spec (see the module's docstring); ``references`` holds the reference level
    of each categorical fixed term, so a factor's slope is coded as its fixed effect is."""
    parts, group, uncorrelated = _parse(spec)
    if len(parts) > MAX_EFFECTS:  # before any column is made
        raise AnalysisError(f"{_shown(spec)} names {len(parts)} terms; at most {MAX_EFFECTS} random effects per "
                            "level are fitted", "--random")
    _require(data, group, "--random")
    levels = levels_of(data[group])
    index = {lv: i for i, lv in enumerate(levels)}
    codes = data[group].map(index).to_numpy(int)
    intercept = "0" not in parts
    names, columns = (["(Intercept)"], [np.ones(len(data))]) if intercept else ([], [])
    for part in parts:
        if part in ("0", "1"):
            continue
        n, c, lv = _fixed_columns(data, part, references.get(part), role="--random")
        if lv is not None and len(lv) < 2:
            raise AnalysisError(f"{part!r} has one level; a random slope needs at least 2", "--random")
        if lv is not None and not names:  # no intercept: R codes the first factor by every level, the first too
            values = data[_column_of(part)]
            n, c = [f"{part}{level}" for level in lv], [(values == level).to_numpy(float) for level in lv]
        names += n
        columns += c
    if len(names) > MAX_EFFECTS:
        raise AnalysisError(f"{_shown(spec)} has {len(names)} random effects per level of {group} (a covariance of "
                            f"{len(names) * (len(names) + 1) // 2} parameters); at most {MAX_EFFECTS} are fitted — "
                            "is a numeric column read as text?", "--random")
    if not names:
        raise AnalysisError(f"{_shown(spec)} has no random effect (0 and nothing else)", "--random")
    if len(set(names)) < len(names):
        raise AnalysisError(f"{_shown(spec)} names a column twice", "--random")
    values = np.column_stack(columns)
    common = dict(group=group, levels=tuple(map(str, levels)), codes=codes)
    if not uncorrelated or len(names) == 1:
        return [RandomTerm(**common, names=tuple(names), values=None if names == ["(Intercept)"] else values)]
    return [RandomTerm(**common, names=(name,), values=None if name == "(Intercept)" else values[:, [i]])
            for i, name in enumerate(names)]


def _check_random(terms: list[RandomTerm], n: int) -> None:
    """Refuse random effects the data cannot support, naming the term: two terms with the same effect on one group,
    as many random effects as observations or more (lme4's check.nobs.vs.nRE), and a slope that never varies within
    any level of its group (a between-group column: it is the intercept over again)."""
    seen: dict[tuple[str, str], RandomTerm] = {}
    for t in terms:
        if len(t.levels) < 2:
            raise AnalysisError(f"{t.label()}: {t.group} has {len(t.levels)} level(s) with data; a grouping factor "
                                "needs at least 2", "--random")
        for name in t.names:
            if (t.group, name) in seen:
                raise AnalysisError(f"{t.label()} repeats the effect {name} of {seen[t.group, name].label()}",
                                    "--random")
            seen[t.group, name] = t
        q = t.width * len(t.levels)
        if q >= n:
            raise AnalysisError(f"{t.label()} has {q} random effects for {n} observations: the number of "
                                "observations must exceed the number of random effects", "--random")
        for j, name in enumerate(t.names):
            column = t.columns()[:, j]
            if name == "(Intercept)":
                continue
            low = np.full(len(t.levels), np.inf)
            high = np.full(len(t.levels), -np.inf)
            np.minimum.at(low, t.codes, column)
            np.maximum.at(high, t.codes, column)
            if not np.any(high > low):
                raise AnalysisError(f"{t.label()}: {name} never varies within a level of {t.group} (each "
                                    f"{t.group} has one value of it), so its slope by {t.group} is not "
                                    "identifiable", "--random")


def build_design(data: pd.DataFrame, response: str, fixed: list[str], random: list[str],
                 reference: str | None = None) -> Design:
    """Model matrices for ``response ~ fixed + (random)``; rows missing any used value are dropped."""
    if not random:
        raise AnalysisError("a mixed model needs at least one random term", "--random")
    _require(data, response, "--response")
    used = [response] + [(_FACTOR.match(t).group(1) if _FACTOR.match(t) else t) for t in fixed]
    used += [_column_of(part) for spec in random for part in _parts(spec)]
    for column in used:
        _require(data, column, "column")
    y_all = pd.to_numeric(data[response], errors="coerce")
    if y_all.isna().all():
        raise AnalysisError("has no numeric values", f"response {response!r}")
    complete = y_all.notna() & data[used[1:]].notna().all(axis=1) & np.isfinite(y_all.fillna(0))
    for column in set(used[1:]):  # an infinite number is as missing as an empty cell
        if pd.api.types.is_numeric_dtype(data[column]) and not pd.api.types.is_bool_dtype(data[column]):
            complete &= np.isfinite(data[column].astype(float).fillna(0))
    rows = data.loc[complete].reset_index(drop=True)
    if len(rows) < 3:
        raise AnalysisError(f"only {len(rows)} complete row(s)", f"response {response!r}")
    names, columns, levels = ["(Intercept)"], [np.ones(len(rows))], []
    references: dict[str, str | None] = {}
    for term in fixed:
        n, c, lv = _fixed_columns(rows, term, reference if term == fixed[0] else None)
        names += n
        columns += c
        if lv is not None:
            levels.append((term, tuple(map(str, lv))))
            references[term] = str(lv[0])
    X = np.column_stack(columns)
    if np.linalg.matrix_rank(X) < X.shape[1]:
        raise AnalysisError("the fixed effects are not estimable (a level is confounded with another term)",
                            "--fixed")
    terms = [t for spec in random for t in _random_terms(rows, spec, references)]
    _check_random(terms, len(rows))
    return Design(response, y_all[complete].to_numpy(float), X, tuple(names), tuple(fixed), tuple(terms),
                  int((~complete).sum()), tuple(levels))


def _parts(spec: str) -> list[str]:
    """The group and the columns a ``--random`` spec names (not 0 or 1)."""
    parts, group, _ = _parse(spec)
    return [group] + [p for p in parts if p not in ("0", "1")]


def _column_of(term: str) -> str:
    m = _FACTOR.match(term.strip())
    return (m.group(1) if m else term).strip()
