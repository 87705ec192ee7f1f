"""Heading scores of candidates at a query: the learned orientation evidence, and the paper's rule.

Both work on the candidates ``idx`` of an :class:`~scenesuggest.suggestion.suggest.Engine` (its cached reference
resolutions and statistics) and return one row of BINS heading-bin scores per candidate; headings are about the
support normal (:mod:`scenesuggest.scenes.poses`), the evidence kinds those of :mod:`scenesuggest.learning.orientation`.
"""

from __future__ import annotations

import numpy as np

from ..learning.observations import WALL, bearings, is_radial, near_wall, wall_heading
from ..learning.orientation import BINS, KINDS, mean_by, pair_kind_rows, turned
from ..scenes import poses
from ..scenes.scene import SURFACE_TYPES


def paper_scores(engine, scores, idx: np.ndarray) -> np.ndarray:
    """(m, BINS) the paper's Σ_r P_relpos · P_relori(h − h_r) for candidates ``idx``."""
    prep = scores.prepared
    out = np.zeros((len(idx), BINS))
    for (ref, relation), dens in zip(prep.references, scores.densities, strict=True):
        seg = engine.pair_sources(ref.category, prep.scene_type, relation, prep.surface_type)[0][idx]
        has = np.flatnonzero(seg >= 0)
        if not len(has):
            continue
        shift = poses.reference_heading(prep.point, prep.normal, ref.transform, is_radial(ref.size))
        out[has] += dens[idx[has], None] * turned(engine.priors.seg_hist[seg[has]].astype(float), shift)
    return out


def evidence(engine, prep, idx: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m, kinds, BINS) log-probabilities of every heading bin from each kind of orientation evidence
    (:mod:`scenesuggest.learning.orientation`), for candidates ``idx`` attached by ``faces``: references of one kind
    averaged."""
    p = engine.priors
    m = len(idx)
    t = SURFACE_TYPES.index(prep.surface_type)
    out = np.zeros((m, len(KINDS), BINS))
    zero = poses.zero_headings(prep.normal)[faces]
    out[:, 0] = turned(p.alpha_log_density[engine.stat_entity[idx], t, faces], zero)
    refs = prep.references
    segs, kinds, angles, rows = [], [], [], []  # per contribution: segment, kind, reference angle, candidate
    if refs:
        transforms = np.array([ref.transform for ref, _ in refs])
        sizes = np.array([ref.size for ref, _ in refs], dtype=float)
        radial = is_radial(sizes)
        fronts = poses.reference_headings(prep.point, prep.normal, transforms, radial)
        towards = bearings(prep.point, prep.normal, transforms, sizes)
        seg = np.stack([engine.pair_sources(ref.category, prep.scene_type, relation, prep.surface_type)[0]
                        for ref, relation in refs])[:, idx]  # (references, m)
        kind_of = np.array([[-1 if k is None else k for k in pair_kind_rows(relation, bool(is_round))]
                            for (_, relation), is_round in zip(refs, radial, strict=True)])  # (references, 2)
        for table, angle in ((0, fronts), (1, towards)):
            usable = (kind_of[:, table] >= 0) & np.isfinite(angle)
            r, c = np.nonzero((seg >= 0) & usable[:, None])
            segs.append(seg[r, c] * 2 + table)
            kinds.append(kind_of[r, table])
            angles.append(angle[r])
            rows.append(c)
    if prep.wall is not None:  # only candidates that would stand at it
        seg = engine.pair_sources(WALL, prep.scene_type, "wall", prep.surface_type)[0][idx]
        seg = np.where(near_wall(prep.wall[1], engine.size[idx]), seg, -1)
        has = np.flatnonzero(seg >= 0)
        segs.append(seg[has] * 2)
        kinds.append(np.full(len(has), KINDS.index("wall")))
        angles.append(np.full(len(has), wall_heading(prep.wall[0], prep.normal)))
        rows.append(has)
    seg, kind, angle, row = (np.concatenate(a) if a else np.zeros(0, np.int64) for a in (segs, kinds, angles, rows))
    if len(seg):
        mean = mean_by(row * len(KINDS) + kind, turned(p.segment_log_density(seg), angle), m * len(KINDS))
        out[:, 1:] = mean.reshape(m, len(KINDS), BINS)[:, 1:]
    return out


def learned_scores(engine, prep, idx: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m, BINS) Σ_k w_k · F_k(h): the learned log-score of every heading bin."""
    weights = engine.weights[idx, SURFACE_TYPES.index(prep.surface_type)]
    return np.einsum("mk,mkb->mb", weights, evidence(engine, prep, idx, faces))
