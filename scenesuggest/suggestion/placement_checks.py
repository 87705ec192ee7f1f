"""Beyond the paper: size- and collision-aware placement, and anchor refinement.

The paper places every category at the click, whatever its size — a large couch clicked into a corner
goes through the walls. :func:`check_fit` tests each candidate's box at its placement against the boxes
of the objects already on the same parent (collision) and against the parent's box (overhang: a desk
lamp hanging over the edge of a side table, a couch through a wall). In ``full`` mode a candidate that
does not fit is turned to the best-scoring heading at which it fits; one that fits at no heading (or any
candidate in ``basic`` mode, which does not orient) has its score multiplied by the penalty. Every
change is reported in the suggestion's notes.

:func:`refine_anchors` moves each candidate, within a radius, to the point of the support plane where
its position term is highest — clicking next to a monitor's ideal spot still puts the keyboard in it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..learning.priors import BINS, FACES
from ..scenes import poses

#: Boxes may touch or overlap by this much (metres) without counting as a collision or an overhang.
TOLERANCE_M = 0.02
#: Anchor refinement moves a candidate only when its position term improves by this factor.
REFINE_GAIN = 1.1


def _boxes(points, normal, faces, sizes, alphas) -> tuple[np.ndarray, np.ndarray]:
    """World AABBs (lo, hi), each (n, 3), of canonical boxes placed by :func:`poses.placements`."""
    t = poses.placements(points, normal, faces, sizes, alphas)
    centre = np.einsum("nij,nj->ni", t[:, :3, :3], np.column_stack([np.zeros(len(sizes)), sizes[:, 1] / 2,
                                                                     np.zeros(len(sizes))])) + t[:, :3, 3]
    half = np.einsum("nij,nj->ni", np.abs(t[:, :3, :3]), sizes / 2)
    return centre - half, centre + half


def _problems(lo, hi, prep, parent, siblings) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(collides, index of the first sibling hit or −1, overhang in metres) for boxes (lo, hi)."""
    if siblings:
        s_lo = np.array([s.world_bbox()[0] for s in siblings])
        s_hi = np.array([s.world_bbox()[1] for s in siblings])
        overlap = np.minimum(hi[:, None], s_hi[None]) - np.maximum(lo[:, None], s_lo[None])
        hit = np.all(overlap > TOLERANCE_M, axis=2)
        collides = hit.any(axis=1)
        first = np.where(collides, np.argmax(hit, axis=1), -1)
    else:
        collides = np.zeros(len(lo), dtype=bool)
        first = np.full(len(lo), -1)
    p_lo, p_hi = parent.world_bbox()
    beyond = np.maximum(p_lo - lo, 0) + np.maximum(hi - p_hi, 0)
    if prep.surface_type.endswith("exterior"):  # standing on the outside: free along the normal
        beyond[:, int(np.argmax(np.abs(prep.normal)))] = 0
    return collides, first, beyond.max(axis=1)


class Fit(NamedTuple):
    """Candidates after :func:`check_fit`: their scores, turns about the surface normal and headings (radians),
    and the notes that explain what was changed, each indexed like the engine's candidates."""

    total: np.ndarray
    alphas: np.ndarray
    headings: np.ndarray
    notes: list[list[str]]


def check_fit(engine, scores, faces, alphas, headings, points, total, notes, mode: str) -> Fit:
    """Re-orient (``full``) or penalise candidates whose box collides or overhangs, for candidates attached by
    ``faces``, turned by ``alphas`` to ``headings`` (radians) at ``points`` (metres, world frame) with scores
    ``total`` and ``notes`` so far; returns them as changed (the arguments are left as they were)."""
    prep = scores.prepared
    scene = prep.query.scene
    parent = scene.objects[prep.query.parent_id]
    siblings = scene.children(parent.id)
    sizes = engine.size
    total, alphas, headings = total.copy(), np.array(alphas, dtype=float), np.array(headings, dtype=float)
    notes = [list(n) for n in notes]
    n = len(sizes)
    zero = headings - alphas
    tries = [np.zeros(n, dtype=int)]  # offsets from the chosen heading, best orientation score first
    if mode == "full":
        face_index = np.array([FACES.index(f) for f in faces])
        order = np.argsort(-engine.heading_scores(scores, np.arange(n), face_index), axis=1, kind="stable")
        chosen = np.round(poses.wrap(headings) / (2 * np.pi / BINS)).astype(int) % BINS
        tries = [order[:, j] - chosen for j in range(BINS)]
    fixed = np.zeros(n, dtype=bool)
    first_problem = None
    for j, offset in enumerate(tries):
        trial = alphas + offset * (2 * np.pi / BINS)
        lo, hi = _boxes(points, prep.normal, faces, sizes, trial)
        collides, hit, overhang = _problems(lo, hi, prep, parent, siblings)
        ok = ~collides & (overhang <= TOLERANCE_M)
        if first_problem is None:
            first_problem = (collides, hit, overhang)
        take = ok & ~fixed
        if j > 0:
            for i in np.flatnonzero(take):
                alphas[i] = trial[i]
                headings[i] = zero[i] + trial[i]
                notes[i].append(f"turned {np.degrees(poses.wrap(offset[i] * 2 * np.pi / BINS)):.0f}° to fit")
        fixed |= take
        if fixed.all():
            break
    collides, hit, overhang = first_problem
    for i in np.flatnonzero(~fixed):
        total[i] *= engine.options.collision_penalty
        if collides[i]:
            s = siblings[hit[i]]
            notes[i].append(f"collides with {s.category} {s.id!r}")
        else:
            notes[i].append(f"overhangs {parent.category} {parent.id!r} by {overhang[i]:.2f} m")
    return Fit(total, alphas, headings, notes)


def plane_samples(point, normal, radius: float) -> np.ndarray:
    """The anchor and 16 points around it on the plane (two rings of 8, at radius/2 and radius)."""
    u = poses.plane_zero(normal)
    v = np.cross(normal, u)
    angles = np.arange(8) * np.pi / 4
    ring = np.column_stack([np.cos(angles), np.sin(angles)])
    offsets = np.vstack([[0.0, 0.0], ring * radius / 2, ring * radius])
    return np.asarray(point) + offsets[:, :1] * u + offsets[:, 1:] * v


def refine_anchors(engine, scores, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) anchor of each candidate and the distance it moved (0 when it stayed)."""
    prep = scores.prepared
    parent = prep.query.scene.objects[prep.query.parent_id]
    samples = plane_samples(prep.point, prep.normal, radius)
    lo, hi = parent.world_bbox()
    inside = np.all((samples >= lo - TOLERANCE_M) & (samples <= hi + TOLERANCE_M), axis=1)
    inside[0] = True
    samples = samples[inside]
    position = engine.position_at(prep, samples)  # (P, n)
    best = np.argmax(position, axis=0)
    gain = position[best, np.arange(position.shape[1])] > REFINE_GAIN * position[0] + 1e-12
    chosen = np.where(gain, best, 0)
    points = samples[chosen]
    return points, np.linalg.norm(points - prep.point, axis=1)
