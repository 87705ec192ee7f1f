"""The random-effects side of a mixed model, in blocks by grouping factor: what both likelihoods solve with.

lme4's parameterisation (Bates, Mächler, Bolker & Walker 2015, §2): random effects b = Λ_θ u with spherical u, where
Λ_θ repeats, for every level of a term's grouping factor, the term's lower-triangular relative covariance factor
T (its entries, column by column, are θ; a variance is σ² (TT')ᵢᵢ). Terms on the same grouping factor (an intercept
and uncorrelated slopes) are stacked into one block per level, so that each row of the data touches one block of
each factor.

The curvature Λ'Z'WZΛ + I is then block-diagonal over the levels of the first (largest) factor — small K×K blocks,
K its effects per level — plus dense blocks for the other factors. Solves and the log-determinant go through the
Schur complement of that block-diagonal part: O(q₁ K³ + q₁ K q₂²) per evaluation instead of O((q₁ K + q₂)³), for q₁
participants and q₂ scene effects — what lets a 2,000-participant study with random slopes fit in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag, cho_factor, cho_solve

from .design import RandomTerm
from .optimum import AT_ZERO, SCAN


class Curvature:
    """The symmetric positive-definite matrix [[D, C], [C', E]] with D block-diagonal (``d``: L blocks K×K): solves
    and the log-determinant through the Schur complement E − C'D⁻¹C."""

    def __init__(self, d: np.ndarray, c: np.ndarray, e: np.ndarray):
        self.d, self.c = d, c
        self.chol = np.linalg.cholesky(d)  # raises LinAlgError when a block is not positive definite
        self.d_inv = np.linalg.inv(d)
        self.schur = cho_factor(e - c.T @ self.solve_first(c)) if e.size else None

    def solve_first(self, g: np.ndarray) -> np.ndarray:
        """D⁻¹g for g of D's rows (a vector, or a matrix of right-hand sides)."""
        levels, k, _ = self.d.shape
        shaped = g.reshape(levels, k, -1)
        return np.matmul(self.d_inv, shaped).reshape(g.shape)

    def solve(self, g: np.ndarray) -> np.ndarray:
        """The solution x of this matrix times x = g (a vector, or a matrix of right-hand sides)."""
        n = self.d.shape[0] * self.d.shape[1]
        if self.schur is None:
            return self.solve_first(g)
        x1 = cho_solve(self.schur, g[n:] - self.c.T @ self.solve_first(g[:n]))
        return np.concatenate([self.solve_first(g[:n] - self.c @ x1), x1])

    def logdet(self) -> float:
        total = 2 * float(np.log(np.diagonal(self.chol, axis1=1, axis2=2)).sum())
        if self.schur is not None:
            total += 2 * float(np.log(np.diag(self.schur[0])).sum())
        return total

    def inverse_times_diagonal(self, g00: np.ndarray, g01: np.ndarray, g10: np.ndarray, g11: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray]:
        """The diagonal blocks of this matrix's inverse times G = [[G00, G01], [G10, G11]], G00 block-diagonal
        like D (``g00``: L×K×K): those of the first part level by level (L×K×K), and the whole lower-right part
        (q₂×q₂), from which a caller takes its own blocks. With P = D⁻¹C and S the Schur complement, the inverse
        is [[D⁻¹ + P S⁻¹ P', −P S⁻¹], [−S⁻¹ P', S⁻¹]]."""
        first = np.matmul(self.d_inv, g00)
        if self.schur is None:
            return first, np.zeros((0, 0))
        levels, k, _ = self.d.shape
        p = self.solve_first(self.c).reshape(levels, k, -1)  # D⁻¹C, level by level
        cd_g00 = np.einsum("lkq,lkj->qlj", self.c.reshape(levels, k, -1), first).reshape(-1, levels * k)
        s_inv = cho_solve(self.schur, np.eye(len(self.schur[0])))  # small: q₂ × q₂
        q = (s_inv @ (cd_g00 - g10)).reshape(-1, levels, k)  # S⁻¹(C'D⁻¹G00 − G10)
        first = first + np.matmul(p, np.moveaxis(q, 0, 1))
        rest = s_inv @ (g11 - p.reshape(levels * k, -1).T @ g01)  # S⁻¹(G11 − C'D⁻¹G01)
        return first, rest


@dataclass(frozen=True)
class _Group:
    """One grouping factor's stacked terms: ``x`` its rows' effect columns (n × K; Z is these, level by level), and
    where each θ goes in the factor's K×K block: ``theta``, ``rows``, ``cols``."""

    name: str
    size: int
    codes: np.ndarray
    x: np.ndarray
    theta: np.ndarray
    rows: np.ndarray
    cols: np.ndarray

    @property
    def width(self) -> int:
        return self.x.shape[1]


def theta_layout(terms) -> list[tuple[int, int]]:
    """Per θ, term by term in the order given, each term's lower triangle column by column as lme4 lays it out:
    (row, column) in its term's factor T."""
    return [(r, c) for t in terms for c in range(t.width) for r in range(c, t.width)]


def term_factors(terms, theta: np.ndarray) -> list[np.ndarray]:
    """Each term's relative covariance factor T (lower triangular, the term's width square) from θ."""
    out, i = [], 0
    for t in terms:
        block = np.zeros((t.width, t.width))
        for r, c in theta_layout([t]):
            block[r, c] = theta[i]
            i += 1
        out.append(block)
    return out


class RandomEffects:
    """Z and Λ_θ of ``terms`` (lme4's (… | group) terms, in the design's order; θ follows that order), grouped by
    factor, the factor with most levels first; u and Λ'Z'r are stacked per factor in that order (``q`` effects in
    all), each factor level by level."""

    def __init__(self, terms: tuple[RandomTerm, ...] | list[RandomTerm]):
        layout = theta_layout(terms)
        self.n_theta = len(layout)
        #: θ entries on a factor's diagonal: bounded below by 0 (lme4's ``lower``)
        self.diagonal = np.array([r == c for r, c in layout])
        starts = np.cumsum([0] + [t.width * (t.width + 1) // 2 for t in terms])
        by_group: dict[str, list[int]] = {}
        for i, t in enumerate(terms):
            by_group.setdefault(t.group, []).append(i)
        groups = []
        for name, members in by_group.items():
            offsets = np.cumsum([0] + [terms[i].width for i in members])
            theta, rows, cols = [], [], []
            for i, off in zip(members, offsets, strict=False):
                for j, (r, c) in enumerate(theta_layout([terms[i]])):
                    theta.append(starts[i] + j)
                    rows.append(off + r)
                    cols.append(off + c)
            first = terms[members[0]]
            x = np.column_stack([terms[i].columns() for i in members])
            groups.append(_Group(name, len(first.levels), first.codes, x, np.array(theta), np.array(rows),
                                 np.array(cols)))
        self.groups = sorted(groups, key=lambda g: -g.size)
        self.sizes = [g.size * g.width for g in self.groups]
        self.offsets = np.concatenate([[0], np.cumsum(self.sizes)[:-1]]).astype(int)
        self.q = int(sum(self.sizes))

    def ways_off_zero(self, x: np.ndarray, scan: tuple[float, ...] = SCAN, plain: bool = True):
        """Points to try from an optimum ``x`` (θ first, then anything else, kept) where a factor's diagonal θ is at
        zero (:func:`analysis.optimum.off_zero`). The deviance depends on each factor T only through TT', and a
        local method stops at a zero diagonal T_jj although a better point lies off it in a direction the bound
        hides: T_jj is set to each small value of ``scan`` (a) as it is (not with ``plain`` false), (b) with the
        rest of column j turned over (TT' is even in the sign of a column), and (c) with the rows below j rotated
        onto columns j, j+1, … (the lower-triangular factor of their covariance: the same TT', with the zero moved
        to the last column), so that T_jj grows into the effects below it."""
        for g, t in zip(self.groups, self.factors(x), strict=True):
            held = set(zip(g.rows.tolist(), g.cols.tolist(), strict=True))
            for j in range(g.width):
                if abs(t[j, j]) >= AT_ZERO:
                    continue
                variants = [t] if plain else []
                if np.any(t[j + 1:, j]):
                    turned = t.copy()
                    turned[j + 1:, j] *= -1
                    variants.append(turned)
                below = t[j + 1:, j:]
                if len(below) and all((r, c) in held for r in range(j + 1, g.width) for c in range(j, r)):
                    try:
                        lower = np.linalg.cholesky(below @ below.T + 1e-12 * np.eye(len(below)))
                    except np.linalg.LinAlgError:
                        lower = None
                    if lower is not None:
                        rotated = t.copy()
                        rotated[j + 1:, j:] = 0.0
                        rotated[j + 1:, j:g.width - 1] = lower
                        variants.append(rotated)
                for variant in variants:
                    for small in scan:
                        v = variant.copy()
                        v[j, j] = small
                        y = x.copy()
                        y[g.theta] = v[g.rows, g.cols]
                        yield y

    def factors(self, theta: np.ndarray) -> list[np.ndarray]:
        """Each factor's K×K lower-triangular block of Λ_θ."""
        out = []
        for g in self.groups:
            t = np.zeros((g.width, g.width))
            t[g.rows, g.cols] = theta[g.theta]
            out.append(t)
        return out

    def zl_u(self, theta: np.ndarray, u: np.ndarray) -> np.ndarray:
        """ZΛu: per row, Σ over factors of its effect columns times T u of its level."""
        total = 0.0
        for g, t, off, size in zip(self.groups, self.factors(theta), self.offsets, self.sizes, strict=True):
            b = u[off:off + size].reshape(g.size, g.width) @ t.T
            total = total + (g.x * b[g.codes]).sum(axis=1)
        return total

    def zt(self, r: np.ndarray) -> np.ndarray:
        """Z'r (r a vector, or a matrix with a column per right-hand side)."""
        if r.ndim == 2:
            return np.column_stack([self.zt(r[:, m]) for m in range(r.shape[1])])
        return np.concatenate([np.column_stack([np.bincount(g.codes, g.x[:, k] * r, minlength=g.size)
                                                for k in range(g.width)]).ravel() for g in self.groups])

    def scale_t(self, theta: np.ndarray, zt_r: np.ndarray) -> np.ndarray:
        """Λ' times a stacked Z'r (from :meth:`zt`)."""
        return self._per_level(theta, zt_r, transpose=True)

    def _per_level(self, theta: np.ndarray, v: np.ndarray, transpose: bool) -> np.ndarray:
        """Λ v (or Λ'v), v stacked as u is (a vector, or a matrix of columns): each level's block times T (T')."""
        parts = []
        for g, t, off, size in zip(self.groups, self.factors(theta), self.offsets, self.sizes, strict=True):
            block = v[off:off + size].reshape(g.size, g.width, -1)
            parts.append(np.matmul(t.T if transpose else t, block).reshape(v[off:off + size].shape))
        return np.concatenate(parts)

    def zl_t(self, theta: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Λ'Z'r."""
        return self.scale_t(theta, self.zt(r))

    def crosstabs(self, w: np.ndarray) -> dict:
        """Z'WZ by blocks of factors: ``(0, 0)`` the first factor's L×K×K diagonal blocks, ``(a, b)`` for a ≤ b
        otherwise (dense)."""
        first = self.groups[0]
        tabs = {(0, 0): self._tabulate(first.codes, first.size, first.x, first.x, w)}
        for a, ga in enumerate(self.groups):
            for b in range(max(a, 1), len(self.groups)):
                gb = self.groups[b]
                block = self._tabulate(ga.codes * gb.size + gb.codes, ga.size * gb.size, ga.x, gb.x, w)
                tabs[a, b] = block.reshape(ga.size, gb.size, ga.width, gb.width).transpose(0, 2, 1, 3) \
                    .reshape(ga.size * ga.width, gb.size * gb.width)
        return tabs

    @staticmethod
    def _tabulate(cells: np.ndarray, size: int, xa: np.ndarray, xb: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Σ over the rows of each cell of w xa xb' (cells × Ka × Kb), in one bincount."""
        ka, kb = xa.shape[1], xb.shape[1]
        products = (w[:, None] * xa)[:, :, None] * xb[:, None, :]
        index = cells[:, None] * (ka * kb) + np.arange(ka * kb)
        return np.bincount(index.ravel(), products.ravel(), minlength=size * ka * kb).reshape(size, ka, kb)

    def curvature(self, theta: np.ndarray, tabs: dict) -> Curvature:
        """Λ'Z'WZΛ + I from the cross-tabulations of :meth:`crosstabs`."""
        ts = self.factors(theta)
        d = ts[0].T @ tabs[0, 0] @ ts[0] + np.eye(self.groups[0].width)
        c, e = self._dense({key: self._scaled(block, *key, ts) for key, block in tabs.items() if key != (0, 0)})
        return Curvature(d, c, e + np.eye(len(e)))

    def _dense(self, blocks: dict) -> tuple[np.ndarray, np.ndarray]:
        """Blocks (a, b), a ≤ b, of a symmetric matrix over the factors, but the first factor's own, as two dense
        matrices: the first factor against the rest, and the rest against itself."""
        n0, rest = self.sizes[0], self.q - self.sizes[0]
        first_rest, rest_rest = np.zeros((n0, rest)), np.zeros((rest, rest))
        for (a, b), block in blocks.items():
            sb = slice(self.offsets[b] - n0, self.offsets[b] - n0 + self.sizes[b])
            if a == 0:
                first_rest[:, sb] = block
                continue
            sa = slice(self.offsets[a] - n0, self.offsets[a] - n0 + self.sizes[a])
            rest_rest[sa, sb] = block
            if a != b:
                rest_rest[sb, sa] = block.T
        return first_rest, rest_rest

    def ztz_times(self, tabs: dict, v: np.ndarray) -> np.ndarray:
        """Z'Z v (from :meth:`crosstabs` with unit weights), v stacked as u is (a vector, or a matrix of
        columns)."""
        parts = [np.zeros_like(v[off:off + size]) for off, size in zip(self.offsets, self.sizes, strict=True)]
        first = self.groups[0]
        v0 = v[:self.sizes[0]]
        parts[0] = parts[0] + np.matmul(tabs[0, 0], v0.reshape(first.size, first.width, -1)).reshape(v0.shape)
        for (a, b), block in tabs.items():
            if (a, b) == (0, 0):
                continue
            va = v[self.offsets[a]:self.offsets[a] + self.sizes[a]]
            vb = v[self.offsets[b]:self.offsets[b] + self.sizes[b]]
            parts[a] = parts[a] + block @ vb
            if a != b:
                parts[b] = parts[b] + block.T @ va
        return np.concatenate(parts)

    def scale(self, theta: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Λ v, v stacked as u is (a vector, or a matrix of columns)."""
        return self._per_level(theta, v, transpose=False)

    def lam_t_ztz(self, theta: np.ndarray, tabs: dict) -> tuple:
        """Λ'Z'Z in the blocks :meth:`Curvature.inverse_times_diagonal` takes: (G00 level by level, G01, G10,
        G11), the first factor against the rest."""
        ts = self.factors(theta)
        first = self.groups[0]
        ztz_0r, ztz_rr = self._dense({key: block for key, block in tabs.items() if key != (0, 0)})
        g01 = np.matmul(ts[0].T, ztz_0r.reshape(first.size, first.width, -1)).reshape(ztz_0r.shape)
        lam_rest_t = block_diag(*[np.kron(np.eye(g.size), t.T) for g, t in zip(self.groups[1:], ts[1:],
                                                                                strict=True)])
        return np.matmul(ts[0].T, tabs[0, 0]), g01, lam_rest_t @ ztz_0r.T, lam_rest_t @ ztz_rr

    def rest_diagonal(self, rest: np.ndarray, k: int) -> np.ndarray:
        """The level-by-level diagonal blocks (L×K×K) of factor ``k`` ≥ 1 in a matrix over the factors after the
        first (the second part of :meth:`Curvature.inverse_times_diagonal`)."""
        g, at = self.groups[k], self.offsets[k] - self.sizes[0]
        own = rest[at:at + self.sizes[k], at:at + self.sizes[k]].reshape(g.size, g.width, g.size, g.width)
        levels = np.arange(g.size)
        return own[levels, :, levels, :]

    def leverages(self, theta: np.ndarray, h: Curvature) -> np.ndarray:
        """The diagonal of ZΛ H⁻¹ Λ'Z' for H = ``h`` (from :meth:`curvature`), one value per row of the data. A row
        touches one level of each factor: its part of ZΛ is a = T₀'x₀ at its level ℓ of the first factor and r over
        the others, and with P = D⁻¹C and S the Schur complement its value is a'D_ℓ⁻¹a + (P_ℓ'a − r)'S⁻¹(P_ℓ'a − r)."""
        ts = self.factors(theta)
        first = self.groups[0]
        a = first.x @ ts[0]
        out = np.einsum("ik,ikj,ij->i", a, h.d_inv[first.codes], a)
        if h.schur is None:
            return out
        n, n0 = len(a), self.sizes[0]
        r = np.zeros((n, self.q - n0))
        for g, t, off in zip(self.groups[1:], ts[1:], self.offsets[1:], strict=True):
            cols = (off - n0) + g.codes[:, None] * g.width + np.arange(g.width)
            r[np.arange(n)[:, None], cols] = g.x @ t
        p = h.solve_first(h.c).reshape(first.size, first.width, -1)
        m = np.einsum("ik,ikq->iq", a, p[first.codes]) - r
        return out + np.einsum("iq,qi->i", m, cho_solve(h.schur, m.T))

    def level_blocks(self, v: np.ndarray) -> list[np.ndarray]:
        """A stacked vector (or matrix of columns) split per factor into levels × effects (× columns)."""
        return [v[off:off + size].reshape(g.size, g.width, *v.shape[1:])
                for g, off, size in zip(self.groups, self.offsets, self.sizes, strict=True)]

    def _scaled(self, block: np.ndarray, a: int, b: int, ts: list[np.ndarray]) -> np.ndarray:
        """T_a' (block) T_b, level by level of both factors."""
        ga, gb = self.groups[a], self.groups[b]
        shaped = block.reshape(ga.size, ga.width, gb.size, gb.width)
        left = np.tensordot(ts[a], shaped, axes=([0], [1]))  # i, l, m, n
        return np.moveaxis(left @ ts[b], 0, 1).reshape(block.shape)
