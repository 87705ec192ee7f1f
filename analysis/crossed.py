"""Crossed random intercepts: the structure both mixed models solve with.

With random intercepts only, b = Λ_θ u where Λ_θ is diagonal (θ_k on the levels of grouping factor k) and Z is
an indicator matrix, so every product the likelihoods need is a weighted cross-tabulation of the factors:
Λ'Z'WZΛ + I has a diagonal block for the first factor (a row belongs to one of its levels) and small dense blocks
for the others. The factors are ordered largest first (participants before scenes), so solves and the
log-determinant go through the Schur complement of that diagonal block: O(q₁ q₂²) per evaluation instead of
O(q³), for q₁ participants and q₂ scenes — what lets a 2,000-participant study fit in seconds.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from .design import RandomTerm


class Curvature:
    """The symmetric positive-definite matrix [[diag(d), c], [c', e]]: solves and the log-determinant through the
    Schur complement e − c' diag(d)⁻¹ c."""

    def __init__(self, d: np.ndarray, c: np.ndarray, e: np.ndarray):
        self.d, self.c = d, c
        self.schur = cho_factor(e - c.T @ (c / d[:, None])) if e.size else None

    def solve(self, g: np.ndarray) -> np.ndarray:
        """The solution x of this matrix times x = g (a vector, or a matrix of right-hand sides)."""
        n = len(self.d)
        d = self.d if g.ndim == 1 else self.d[:, None]
        if self.schur is None:
            return g / d
        x1 = cho_solve(self.schur, g[n:] - self.c.T @ (g[:n] / d))
        return np.concatenate([(g[:n] - self.c @ x1) / d, x1])

    def logdet(self) -> float:
        total = float(np.log(self.d).sum())
        if self.schur is not None:
            total += 2 * float(np.log(np.diag(self.schur[0])).sum())
        return total


class CrossedIntercepts:
    """The random-effects side of a model with one random intercept per grouping factor, ``terms`` ordered largest
    first. ``theta`` holds one relative standard deviation per factor, in that order; u and Λ'Z'r are stacked
    per factor in that order too (``q`` levels in all)."""

    def __init__(self, terms: tuple[RandomTerm, ...] | list[RandomTerm]):
        if any(t.slope is not None for t in terms):
            raise ValueError("random slopes have no crossed-intercepts structure")
        self.sizes = [len(t.levels) for t in terms]
        self.offsets = np.concatenate([[0], np.cumsum(self.sizes)[:-1]]).astype(int)
        self.codes = [t.codes for t in terms]
        self.cols = [t.codes + off for t, off in zip(terms, self.offsets, strict=True)]
        self.k, self.q = len(terms), int(sum(self.sizes))

    def zl_u(self, theta: np.ndarray, u: np.ndarray) -> np.ndarray:
        """ZΛu: each row's sum of θ_k u over the levels it belongs to."""
        return sum(th * u[c] for th, c in zip(theta, self.cols, strict=True))

    def zt(self, r: np.ndarray) -> np.ndarray:
        """Z'r: per level, the sum of r over its rows (r a vector, or a matrix with a column per right-hand side)."""
        if r.ndim == 1:
            return np.concatenate([np.bincount(c, r, minlength=size) for c, size in zip(self.codes, self.sizes,
                                                                                        strict=True)])
        return np.column_stack([self.zt(r[:, j]) for j in range(r.shape[1])])

    def scale(self, theta: np.ndarray) -> np.ndarray:
        """The diagonal of Λ_θ: θ_k repeated over the levels of factor k."""
        return np.repeat(np.asarray(theta, dtype=float), self.sizes)

    def zl_t(self, theta: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Λ'Z'r."""
        z = self.zt(r)
        return z * (self.scale(theta) if z.ndim == 1 else self.scale(theta)[:, None])

    def crosstabs(self, w: np.ndarray) -> dict:
        """Z'WZ by blocks: ``(0, 0)`` the first factor's diagonal (a vector), ``(a, b)`` for a ≤ b otherwise."""
        tabs = {(0, 0): np.bincount(self.codes[0], w, minlength=self.sizes[0])}
        for a in range(self.k):
            for b in range(max(a, 1), self.k):
                block = np.bincount(self.codes[a] * self.sizes[b] + self.codes[b], w,
                                    minlength=self.sizes[a] * self.sizes[b])
                tabs[a, b] = block.reshape(self.sizes[a], self.sizes[b])
        return tabs

    def curvature(self, theta: np.ndarray, tabs: dict) -> Curvature:
        """Λ'Z'WZΛ + I from the cross-tabulations of :meth:`crosstabs`."""
        d = theta[0] ** 2 * tabs[0, 0] + 1
        c = (np.hstack([theta[0] * theta[b] * tabs[0, b] for b in range(1, self.k)]) if self.k > 1
             else np.zeros((self.sizes[0], 0)))
        first = self.sizes[0]
        e = np.eye(self.q - first)
        for a in range(1, self.k):
            for b in range(a, self.k):
                sa = slice(self.offsets[a] - first, self.offsets[a] - first + self.sizes[a])
                sb = slice(self.offsets[b] - first, self.offsets[b] - first + self.sizes[b])
                block = theta[a] * theta[b] * tabs[a, b]
                e[sa, sb] += block
                if a != b:
                    e[sb, sa] += block.T
        return Curvature(d, c, e)
