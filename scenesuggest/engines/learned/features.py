"""The learned engine's two feature tables: one row per candidate category for ranking, and one row per candidate
× reference frame for orientation.

Ranking (:data:`RANKING`): the paper's terms as the paper's engine computes them for the click (occurrence,
support surface, position, their score), the candidate's size, the click's surface and scene type, and the
context of :mod:`.context`. Names are stable: they label a trained model's columns and the ``--explain`` output.

Orientation (:data:`FRAMES`): each frame proposes a heading about the surface normal —

===================  ==========================================================================================
``product``          the weighted product of every kind of evidence (the paper engine's ``full`` orientation)
``pose``             the canonical pose, unturned (what ``basic`` shows)
``canonical``        the most frequent turn from the canonical pose
``parent_front``     the most frequent heading relative to the parent's front
``parent_bearing``   … relative to the bearing towards the parent
``sibling_front``    … relative to the fronts of the other objects on the parent
``sibling_bearing``  … relative to the bearings towards them
``wall``             … relative to the nearest wall's inward normal
===================  ==========================================================================================

— and its row (:data:`ORIENTATION`) says how much every kind of evidence supports that heading, how peaked the
frame's own evidence is, how many other frames agree with it, and the click's context. A classifier learns from
them which frame to trust per query (:meth:`.engine.LearnedEngine.frame_headings`).
"""

from __future__ import annotations

import numpy as np

from ...learning.observations import is_radial
from ...learning.orientation import BINS, KINDS, decide
from ...scenes import poses
from ...scenes.scene import SURFACE_TYPES
from ...suggestion import headings
from ...suggestion.suggest import Engine, Scores
from .context import ContextStats

PAPER_TERMS = ("occurrence", "surface", "position", "paper_score", "log_paper_score", "log_occurrence_surface")
CONTEXT = ("likely_height", "likely_edge", "likely_wall", "likely_area", "likely_free", "given_scene_max",
           "given_scene_mean", "given_scene_lift", "given_parent_max", "given_parent_mean", "given_near_max",
           "given_near_mean", "frequency", "in_scenes", "in_scene_type", "count_in_scene", "count_on_parent",
           "click_height", "click_edge", "click_wall", "click_area", "click_free", "click_objects_on_parent",
           "click_objects_in_scene", "click_categories_near")
RANKING = (*PAPER_TERMS, "log_footprint", "log_height", "footprint_vs_area", "free_vs_size", "surface_type",
           "scene_type", *CONTEXT)
RANKING_CATEGORICAL = ("surface_type", "scene_type")

FRAMES = ("product", "pose", "canonical", *KINDS[1:])
#: Headings this close (radians) count as the same.
AGREE = np.radians(20.0)
ORIENTATION = ("frame", "available", "agreeing", "is_pose", "is_product", "peak", "peak_mass", "weight",
               *(f"support_{k}" for k in KINDS), "support_product", "surface_type", "kept_pose",
               "references", "wall_m", "log_footprint", "radial")
ORIENTATION_CATEGORICAL = ("frame", "surface_type")
BIN = 2 * np.pi / BINS


def ranking_features(engine: Engine, stats: ContextStats, scores: Scores) -> np.ndarray:
    """(candidates, len(RANKING)) float32: the ranking row of every candidate of ``engine`` for a scored click."""
    prep = scores.prepared
    n = len(engine.candidates)
    context, click = stats.features(prep.query.scene, prep.query.scene.objects[prep.query.parent_id], prep.point,
                                    prep.normal, prep.scene_type)
    footprint = np.log(engine.size[:, 0] * engine.size[:, 2] + 1e-4)
    columns = {
        "occurrence": scores.occurrence, "surface": scores.surface, "position": scores.position,
        "paper_score": scores.total, "log_paper_score": np.log(scores.total + 1e-6),
        "log_occurrence_surface": np.log(scores.occurrence * scores.surface + 1e-6),
        "log_footprint": footprint, "log_height": np.log(engine.size[:, 1] + 1e-3),
        "footprint_vs_area": footprint - click["area"],
        "free_vs_size": np.full(n, np.log(click["free"] + 0.01)) - np.log(engine.size[:, [0, 2]].max(axis=1) / 2
                                                                           + 0.01),
        "surface_type": np.full(n, SURFACE_TYPES.index(prep.surface_type)),
        "scene_type": np.full(n, stats.type_index.get(prep.scene_type, -1)),
        **context,
    }
    rows = np.empty((n, len(RANKING)), dtype=np.float32)
    for k, name in enumerate(RANKING):
        rows[:, k] = columns[name]
    return rows


def _wrapped(a: np.ndarray) -> np.ndarray:
    return np.abs((a + np.pi) % (2 * np.pi) - np.pi)


def _at(values: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """``values`` (m, BINS) or (m, K, BINS) read at ``heading`` (m, F) radians, linearly between bins: (m, F)
    or (m, K, F)."""
    flat = values.ndim == 2
    v = values[:, None, :] if flat else values
    x = np.mod(heading / BIN, BINS)
    lo = np.floor(x).astype(np.int64)
    frac = (x - lo)[:, None, :]
    at = np.broadcast_to(lo[:, None, :], (v.shape[0], v.shape[1], lo.shape[1])) % BINS
    out = (1 - frac) * np.take_along_axis(v, at, axis=2) + frac * np.take_along_axis(v, (at + 1) % BINS, axis=2)
    return out[:, 0] if flat else out


def frame_proposals(engine: Engine, scores: Scores, idx: np.ndarray, faces: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(headings (m, FRAMES) radians, orientation rows (m, FRAMES, len(ORIENTATION)) float32) for candidates
    ``idx`` attached by ``faces`` (indices into FACES) — see the module docstring."""
    prep = scores.prepared
    m = len(idx)
    t = SURFACE_TYPES.index(prep.surface_type)
    zero = poses.zero_headings(prep.normal)[faces]
    evidence = headings.evidence(engine, prep, idx, faces)  # (m, kinds, BINS) log-probabilities
    weights = engine.weights[idx, t]  # (m, kinds)
    product = np.einsum("mk,mkb->mb", weights, evidence)
    chosen, kept = decide(product, zero)
    flat = (evidence.max(axis=2) - evidence.min(axis=2)) < 1e-9  # (m, kinds): nothing observed
    peak_bin = np.argmax(evidence, axis=2)
    heading = np.mod(np.column_stack([chosen, zero, np.where(flat, zero[:, None], peak_bin * BIN)]), 2 * np.pi)
    n_frames = len(FRAMES)
    available = np.ones((m, n_frames))
    available[:, 2:] = ~flat
    agreeing = (_wrapped(heading[:, :, None] - heading[:, None, :]) < AGREE).sum(axis=2) - 1
    q = np.exp(evidence - evidence.max(axis=2, keepdims=True))
    q /= q.sum(axis=2, keepdims=True)
    mass = np.take_along_axis(np.roll(q, 1, axis=2) + q + np.roll(q, -1, axis=2), peak_bin[:, :, None], axis=2)[..., 0]
    own_peak, own_mass, own_weight = (np.zeros((m, n_frames)) for _ in range(3))
    own_peak[:, 2:], own_mass[:, 2:], own_weight[:, 2:] = evidence.max(axis=2), mass, weights
    support = _at(evidence - evidence.max(axis=2, keepdims=True), heading)  # (m, kinds, frames)
    product_support = _at(product - product.max(axis=1, keepdims=True), heading)
    footprint = np.log(engine.size[idx, 0] * engine.size[idx, 2] + 1e-4)
    radial = is_radial(engine.size[idx]).astype(float)
    wall_m = prep.wall[1] if prep.wall is not None else 5.0
    rows = np.zeros((m, n_frames, len(ORIENTATION)), dtype=np.float32)
    rows[..., 0] = np.arange(n_frames)
    rows[..., 1] = available
    rows[..., 2] = agreeing
    rows[..., 3] = _wrapped(heading - zero[:, None]) < 1e-3
    rows[..., 4] = _wrapped(heading - heading[:, :1]) < 1e-3
    rows[..., 5], rows[..., 6], rows[..., 7] = own_peak, own_mass, own_weight
    rows[..., 8:8 + len(KINDS)] = np.transpose(support, (0, 2, 1))
    rows[..., 8 + len(KINDS)] = product_support
    rows[..., 9 + len(KINDS)] = SURFACE_TYPES.index(prep.surface_type)
    rows[..., 10 + len(KINDS)] = kept[:, None]
    rows[..., 11 + len(KINDS)] = len(prep.references)
    rows[..., 12 + len(KINDS)] = wall_m
    rows[..., 13 + len(KINDS)] = footprint[:, None]
    rows[..., 14 + len(KINDS)] = radial[:, None]
    return heading, rows


__all__ = ["FRAMES", "ORIENTATION", "RANKING", "frame_proposals", "ranking_features"]
