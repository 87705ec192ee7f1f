"""Relative position and orientation priors: pair observations grouped by reference and child, as arrays.

Every :class:`~scenesuggest.learning.observations.Pair` is expanded over the child's and the reference's entities (the
category and the subtrees above it, :mod:`scenesuggest.learning.priors`) and over its scene type and all scene types
(``*``). A *group* is a reference key (reference entity, scene type, relation, surface type); a *segment* is one child
entity within a group, holding its samples:

* relative position — a 2-D Gaussian KDE of the offsets δ (metres), bandwidth by Scott's rule, at least
  MIN_BANDWIDTH_M (10 cm: chosen on near-copy-grouped folds of both corpora — wider floors raise held-out MRR a
  little further, 20 cm by 0.009 on Stanford, but blur where a mouse goes beside a keyboard),
  divided by its peak (``seg_weight`` = 1 / peak), so it is a relative likelihood in [0, 1];
* relative orientation — counts of θ and of φ in 36 bins of 10° (``seg_theta_n``, ``seg_phi_n``).

The expansion is vectorised: pairs that share (category, reference category, scene type, relation, surface
type) share their expansion, which is built once and repeated. Wall pairs are kept under all scene types only
(a wall is no object of a room type, so its statistics are never read per type) and are also pooled over every category
(the entity ``*``): what "at a wall" means for furniture in general stands in for a category that was seldom
seen at one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scenes.scene import SURFACE_TYPES
from .angle_bins import angle_bins, bin_counts
from .observations import RELATIONS, Pair

MIN_BANDWIDTH_M = 0.1
#: Peak normalisers are evaluated at up to this many sample points per KDE; KDEs of up to SMALL_SEGMENT
#: samples are normalised together, exactly.
PEAK_POINTS = 128
SMALL_SEGMENT = 24


@dataclass
class Expanded:
    """Pair rows after expansion, sorted by (group, child, offset, θ): what LOO statistics need as well."""

    group: np.ndarray  # (rows,) group of each row
    child: np.ndarray  # (rows,) child entity
    xy: np.ndarray  # (rows, 2) offsets, metres
    theta: np.ndarray  # (rows,) radians, NaN where undefined
    phi: np.ndarray
    pair: np.ndarray  # (rows,) index of the original pair
    segment: np.ndarray  # (rows,) segment of each row
    keys: list[tuple[int, int, int, int]]  # group → (reference entity, scene index, relation, surface type)


def expand_pairs(pairs: list[Pair], expand: dict[str, list[int]], s_index: dict[str, int], any_s: int,
                 pooled: int | None = None) -> Expanded:
    """Expand pairs over entities and scene keys (see the module docstring); wall pairs also count for the
    ``pooled`` entity (every category at once)."""
    key_of: dict[tuple, int] = {}
    pair_key = np.array([key_of.setdefault((p.category, p.ref_category, p.scene_type, p.relation, p.surface_type),
                                           len(key_of)) for p in pairs], dtype=np.int64)
    group_of: dict[tuple[int, int, int, int], int] = {}
    combo_group, combo_child, combo_len = [], [], []
    for category, ref_category, scene_type, relation, surface_type in key_of:
        r, t = RELATIONS.index(relation), SURFACE_TYPES.index(surface_type)
        n = 0
        scenes = [any_s] if relation == "wall" else sorted({s_index[scene_type], any_s})
        for e_ref in expand[ref_category]:
            for s in scenes:
                g = group_of.setdefault((e_ref, s, r, t), len(group_of))
                for e_child in expand[category] + ([pooled] if relation == "wall" and pooled is not None else []):
                    combo_group.append(g)
                    combo_child.append(e_child)
                    n += 1
        combo_len.append(n)
    combo_len = np.array(combo_len, dtype=np.int64)
    combo_start = np.r_[0, np.cumsum(combo_len)[:-1]] if len(combo_len) else combo_len
    per_pair = combo_len[pair_key] if len(pairs) else np.zeros(0, np.int64)
    row_pair = np.repeat(np.arange(len(pairs)), per_pair)
    first_row = np.r_[0, np.cumsum(per_pair)[:-1]] if len(pairs) else per_pair
    row_combo = (combo_start[pair_key][row_pair] + np.arange(len(row_pair)) - first_row[row_pair]).astype(np.int64)

    keys = sorted(group_of)  # renumber groups in key order so that files are deterministic
    renumber = np.empty(len(keys), dtype=np.int64)
    for new, key in enumerate(keys):
        renumber[group_of[key]] = new
    combo_group = np.array(combo_group, dtype=np.int64)
    group = renumber[combo_group[row_combo]] if len(row_combo) else np.zeros(0, np.int64)
    child = np.array(combo_child, dtype=np.int64)[row_combo] if len(row_combo) else np.zeros(0, np.int64)
    xy_all = np.array([p.offset for p in pairs], dtype=np.float32).reshape(-1, 2)
    theta_all = np.array([p.theta for p in pairs], dtype=np.float32)
    phi_all = np.array([p.phi for p in pairs], dtype=np.float32)
    xy, theta = xy_all[row_pair], theta_all[row_pair]
    order = np.lexsort((theta, xy[:, 1], xy[:, 0], child, group))
    group, child, xy, theta, row_pair = group[order], child[order], xy[order], theta[order], row_pair[order]
    if len(group):
        segment = np.r_[0, np.cumsum((np.diff(group) != 0) | (np.diff(child) != 0))]
    else:
        segment = np.zeros(0, np.int64)
    return Expanded(group, child, xy, theta, phi_all[row_pair], row_pair, segment, keys)


def pair_arrays(x: Expanded, progress) -> dict[str, np.ndarray]:
    """The learned arrays of the position and orientation priors (see the module docstring)."""
    starts = np.flatnonzero(np.r_[True, np.diff(x.segment) != 0]) if len(x.group) else np.zeros(0, np.int64)
    counts = np.diff(np.r_[starts, len(x.group)])
    bandwidth = _bandwidths(x.xy.astype(np.float64), starts, counts)
    peaks = np.zeros(len(starts))
    small = counts <= SMALL_SEGMENT
    peaks[small] = _small_peaks(x.xy, starts[small], counts[small], bandwidth[small])
    for i in progress(np.flatnonzero(~small), "fitting densities"):
        peaks[i] = _peak(x.xy[starts[i]:starts[i] + counts[i]].astype(np.float64), bandwidth[i])
    n = len(starts)
    return {
        "group_keys": np.array(x.keys, dtype=np.int32).reshape(-1, 4),
        "seg_group": x.group[starts].astype(np.int32), "seg_child": x.child[starts].astype(np.int32),
        "seg_start": starts.astype(np.int64), "seg_count": counts.astype(np.int32),
        "seg_bandwidth": bandwidth.astype(np.float32), "seg_weight": (1.0 / peaks).astype(np.float32),
        "seg_theta_n": bin_counts(x.segment, angle_bins(x.theta), n),
        "seg_phi_n": bin_counts(x.segment, angle_bins(x.phi), n), "pair_xy": x.xy,
    }


def _bandwidths(xy: np.ndarray, starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Scott's rule per segment (σ · n^(−1/6) per axis), at least MIN_BANDWIDTH_M."""
    if not len(starts):
        return np.zeros((0, 2))
    n = counts[:, None].astype(np.float64)
    mean = np.add.reduceat(xy, starts, axis=0) / n
    var = np.maximum(np.add.reduceat(xy ** 2, starts, axis=0) / n - mean ** 2, 0.0)
    return np.maximum(np.sqrt(var) * n ** (-1 / 6), MIN_BANDWIDTH_M)


def _small_peaks(xy: np.ndarray, starts: np.ndarray, counts: np.ndarray, bandwidth: np.ndarray) -> np.ndarray:
    """Peaks of many small KDEs at once: samples padded to SMALL_SEGMENT, all pairs evaluated together."""
    out = np.zeros(len(starts))
    for lo in range(0, len(starts), 4096):
        st, ct, bw = starts[lo:lo + 4096], counts[lo:lo + 4096], bandwidth[lo:lo + 4096]
        offsets = np.arange(SMALL_SEGMENT)
        valid = offsets[None, :] < ct[:, None]
        idx = np.where(valid, st[:, None] + offsets[None, :], st[:, None])
        pts = xy[idx].astype(np.float64) / bw[:, None, :]
        d2 = ((pts[:, :, None, :] - pts[:, None, :, :]) ** 2).sum(axis=3)
        k = np.exp(-0.5 * d2) * valid[:, None, :]
        out[lo:lo + 4096] = np.where(valid, k.sum(axis=2), 0.0).max(axis=1)
    return out


def _peak(points: np.ndarray, bandwidth: np.ndarray) -> float:
    """The largest value of Σ exp(−q/2) over the sample points: all of them for small samples; for large ones
    the points of the densest cells of a bandwidth-sized grid (where a KDE's peak lies), PEAK_POINTS at most."""
    unique, weight = np.unique(points, axis=0, return_counts=True)
    if len(unique) <= PEAK_POINTS:
        probe = unique
    else:
        cells, cell_of = np.unique(np.floor(unique / bandwidth).astype(np.int64), axis=0, return_inverse=True)
        cell_weight = np.bincount(cell_of.reshape(-1), weights=weight, minlength=len(cells))
        rank = np.argsort(np.argsort(-cell_weight, kind="stable"), kind="stable")[cell_of.reshape(-1)]
        probe = unique[np.argsort(rank, kind="stable")[:PEAK_POINTS]]
    best = 0.0
    for chunk in np.array_split(probe, max(1, len(probe) // 64)):
        d = (chunk[:, None, :] - unique[None, :, :]) / bandwidth
        best = max(best, float((np.exp(-0.5 * (d ** 2).sum(axis=2)) @ weight).max()))
    return best
