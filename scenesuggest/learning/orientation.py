"""The orientation prior of ``full`` mode: which way a category faces, by which references, trusted how far.

Headings are angles about the support normal (:mod:`scenesuggest.scenes.poses`), in BINS bins of 10° (bin b is centred
on b·10°). Each *kind* of evidence gives, for one candidate category, a log-probability of every heading bin:

=================  =====================================================================================
``canonical``      the turn from the canonical pose of the attachment face (how the category is turned in
                   the corpus's own frame: potted plants and posters are never turned)
``parent_front``   θ, the heading relative to the parent's front (the paper's term, for the parent)
``parent_bearing`` φ, the heading relative to the bearing from the object to the parent's centre
``sibling_front``  θ relative to each other object on the same parent (averaged over them)
``sibling_bearing`` φ relative to each other object on the same parent (chairs face the table)
``wall``           θ relative to the nearest wall's inward normal (desks and dressers back onto walls)
=================  =====================================================================================

A histogram of counts ``c`` (n observations) gives log-probabilities ``log((smooth(c) + a/B) / (n + a))``
(:func:`log_density`; ``smooth`` is the (1, 2, 1)/4 kernel, ``a`` = PSEUDO_COUNT), so an expert that has seen
little is nearly flat and changes no decision. The kinds are combined as a weighted product of experts,
``S(h) = Σ_k w_k · F_k(h)``, with non-negative weights per category learned from the training data
(:func:`fit_weights`): a conditional logit over the heading bins whose features leave each training object's
own scene and its near-copies out (:mod:`scenesuggest.corpora.folds`), so that a kind earns weight only by predicting
headings in scenes it has not seen. Categories with fewer than MIN_FIT_OBSERVATIONS observations take their taxonomy
parent's weights, and fitted weights are shrunk towards them. A plain sum of peak-normalised histograms — the
paper's rule — lets many flat references outvote one sharp one; a weighted product does not.

Decision (:func:`decide`): the heading bin that maximises ``S``, unless the canonical heading holds at least
FALLBACK of that bin's probability mass (each bin with its two neighbours): then the canonical heading, so that
an object whose heading the priors cannot tell keeps the pose it would have in ``basic`` mode.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize

from ..scenes.frames import FACES
from ..scenes.scene import SURFACE_TYPES
from ..scenes.taxonomy import MIN_OBSERVATIONS
from .angle_bins import BINS, angle_bins, bin_counts
from .observations import POOLED

BIN = 2 * math.pi / BINS
KINDS = ("canonical", "parent_front", "parent_bearing", "sibling_front", "sibling_bearing", "wall")
PSEUDO_COUNT = 3.0
MIN_FIT_OBSERVATIONS = 20
#: Shrinkage of a category's weights towards its parent's (and of the global weights towards 1).
SHRINK = 5.0
GLOBAL_SHRINK = 1.0
FALLBACK = 0.8
SWITCH_TOLERANCE = math.radians(45.0)


def smooth(counts: np.ndarray) -> np.ndarray:
    """The (1, 2, 1)/4 circular kernel along the last axis."""
    wrapped = np.concatenate([counts[..., -1:], counts, counts[..., :1]], axis=-1)
    return (wrapped[..., :-2] + 2 * counts + wrapped[..., 2:]) / 4


def log_density(counts: np.ndarray) -> np.ndarray:
    """Log-probabilities of the heading bins from histogram counts (last axis: BINS), see the module docstring."""
    counts = np.maximum(np.asarray(counts, dtype=float), 0.0)
    n = counts.sum(axis=-1, keepdims=True)
    return np.log((smooth(counts) + PSEUDO_COUNT / BINS) / (n + PSEUDO_COUNT))


#: _ROTATIONS[s, h] = (h + s) mod BINS
_ROTATIONS = (np.arange(BINS)[None, :] + np.arange(BINS)[:, None]) % BINS


def turned(values: np.ndarray, angle) -> np.ndarray:
    """``values`` over relative bins (…, BINS) re-indexed to absolute headings: out[h] = values[h − angle],
    linearly interpolated between bins; ``angle`` (radians) broadcasts over the leading axes."""
    values = np.asarray(values, dtype=float)
    rows = values.reshape(-1, BINS)
    shift = np.broadcast_to(np.asarray(angle, dtype=float) / BIN, values.shape[:-1]).reshape(-1)
    s0 = np.floor(shift)
    frac = (shift - s0)[:, None]
    # a[h] = values[(h − s0) mod BINS], b[h] = values[(h − s0 − 1) mod BINS] = a[h − 1]
    at = _ROTATIONS[(-s0.astype(np.int64)) % BINS]
    at += (np.arange(len(rows)) * BINS)[:, None]
    a = rows.ravel()[at]
    out = np.empty_like(a)
    out[:, 1:], out[:, 0] = a[:, :-1], a[:, -1]
    out *= frac
    a *= 1 - frac
    out += a
    return out.reshape(values.shape)


def heading_bin(angle) -> np.ndarray:
    """The bin of a heading (radians)."""
    return np.round(np.mod(angle, 2 * math.pi) / BIN).astype(np.int64) % BINS


def _neighbourhood(q: np.ndarray) -> np.ndarray:
    return np.roll(q, 1, axis=-1) + q + np.roll(q, -1, axis=-1)


def decide(score: np.ndarray, canonical) -> tuple[np.ndarray, np.ndarray]:
    """(heading in radians, whether the canonical heading was kept) for scores (n, BINS) and canonical headings
    (n,); see the module docstring."""
    score = np.atleast_2d(score)
    canonical = np.asarray(canonical, dtype=float).reshape(-1)
    q = np.exp(score - score.max(axis=1, keepdims=True))
    mass = _neighbourhood(q / q.sum(axis=1, keepdims=True))
    best = np.argmax(score, axis=1)
    rows = np.arange(len(best))
    keep = mass[rows, heading_bin(canonical)] >= FALLBACK * mass[rows, best] - 1e-12
    return np.where(keep, canonical, best * BIN), keep


def _fit_one(x: np.ndarray, y: np.ndarray, prior: np.ndarray, shrink: float) -> np.ndarray:
    """Weights ≥ 0 maximising Σ_i log softmax(w · x_i)[y_i] − shrink/2 · |w − prior|² (x: (n, K, BINS))."""
    rows = np.arange(len(y))
    observed = x[rows, :, y]  # (n, K)

    def objective(w):
        s = np.einsum("k,nkb->nb", w, x)
        top = s.max(axis=1, keepdims=True)
        e = np.exp(s - top)
        z = e.sum(axis=1)
        p = e / z[:, None]
        nll = -(s[rows, y] - top[:, 0] - np.log(z)).sum() + 0.5 * shrink * ((w - prior) ** 2).sum()
        grad = -(observed - np.einsum("nb,nkb->nk", p, x)).sum(axis=0) + shrink * (w - prior)
        return nll, grad

    result = minimize(objective, prior.copy(), jac=True, method="L-BFGS-B", bounds=[(0.0, None)] * x.shape[1])
    return result.x


def _within(a: np.ndarray, b: np.ndarray, tolerance: float) -> np.ndarray:
    d = np.mod(a - b, 2 * math.pi)
    return np.minimum(d, 2 * math.pi - d) <= tolerance


def fit_weights(features: np.ndarray, headings: np.ndarray, canonical: np.ndarray, chains: list[list[int]],
                surface: np.ndarray, n_entities: int, n_surfaces: int, parent_of: dict[int, int]) -> np.ndarray:
    """Weights (n_entities, n_surfaces, K) from training features (n, K, BINS), the true headings (n,) and the
    canonical headings (n,), radians, and each observation's surface type (n,).

    Levels: a global fit over all observations; a fit per surface type (what counts for furniture on a floor
    differs from clutter on a desk), with the global fit as its prior; a fit per entity of ``chains[i]`` (the
    entities observation i counts for, specific first; ``parent_of``: an entity's next more general entity),
    with the nearest fitted entity above it — else the global fit — as its prior, one weight vector for every
    surface type. Entities with fewer than MIN_FIT_OBSERVATIONS observations have no fit of their own: they
    take the nearest fitted entity's weights, and without one their surface type's. A fit that does not place
    more of its observations within SWITCH_TOLERANCE of the truth than the canonical heading does becomes zero
    weights: the canonical heading is kept. (The features leave each observation's scene group out; the
    weights are scored on the observations they were fitted to.)"""
    k = features.shape[1]
    targets = heading_bin(headings)

    def fit(rows: np.ndarray, prior: np.ndarray, shrink: float) -> np.ndarray:
        w = _fit_one(features[rows], targets[rows], prior, shrink)
        predicted, _ = decide(np.einsum("k,nkb->nb", w, features[rows]), canonical[rows])
        model = _within(predicted, headings[rows], SWITCH_TOLERANCE).mean()
        kept = _within(canonical[rows], headings[rows], SWITCH_TOLERANCE).mean()
        return w if model > kept else np.zeros(k)

    glob = _fit_one(features, targets, np.ones(k), GLOBAL_SHRINK) if len(targets) else np.ones(k)
    by_surface = []
    for t in range(n_surfaces):
        rows = np.flatnonzero(surface == t)
        by_surface.append(fit(rows, glob, SHRINK) if len(rows) >= MIN_FIT_OBSERVATIONS else glob)
    members: dict[int, list[int]] = {}
    for i, chain in enumerate(chains):
        for e in chain:
            members.setdefault(e, []).append(i)
    own: dict[int, np.ndarray | None] = {}

    def fitted(e: int | None) -> np.ndarray | None:
        """The entity's own weights, or those of the nearest fitted entity above it (None: none is)."""
        if e is None:
            return None
        if e not in own:
            above = fitted(parent_of.get(e))
            rows = np.array(members.get(e, []), dtype=np.int64)
            own[e] = fit(rows, glob if above is None else above, SHRINK) if len(rows) >= MIN_FIT_OBSERVATIONS \
                else above
        return own[e]

    dense = np.zeros((n_entities, n_surfaces, k), dtype=np.float32)
    for e in range(n_entities):
        w = fitted(e)
        dense[e] = w if w is not None else np.array(by_surface)
    return dense


# --- learning from a corpus ------------------------------------------------------------------------------------
#: Which kind of evidence a pair gives, by relation: (θ kind, φ kind).
PAIR_KINDS = {"parent": ("parent_front", "parent_bearing"), "sibling": ("sibling_front", "sibling_bearing"),
              "wall": ("wall", None)}


def pair_kind_rows(relation: str, radial: bool) -> tuple[int | None, int | None]:
    """Kind indices of a pair's θ and φ evidence (θ of a reference without a front is its bearing: not counted
    twice)."""
    front, bearing = PAIR_KINDS[relation]
    return (None if radial and relation != "wall" else KINDS.index(front)), (
        KINDS.index(bearing) if bearing else None)


def _or_minus_one(k: int | None) -> int:
    return -1 if k is None else k


def mean_by(rows: np.ndarray, values: np.ndarray, n_rows: int) -> np.ndarray:
    """(n_rows, BINS): the mean of ``values`` (m, BINS) over each row index of ``rows`` (0 where none); each
    row's values are summed in their order in ``values``."""
    rows = np.asarray(rows, dtype=np.int64)
    if not len(rows):
        return np.zeros((n_rows, BINS))
    cells = (rows[:, None] * BINS + np.arange(BINS)).ravel()
    sums = np.bincount(cells, weights=np.asarray(values, dtype=float).ravel(), minlength=n_rows * BINS)
    counts = np.bincount(rows, minlength=n_rows)
    return sums.reshape(n_rows, BINS) / np.maximum(counts, 1)[:, None]


class _GroupCounts:
    """Samples and θ, φ counts of each (segment, scene group): what leaving a scene group out subtracts."""

    def __init__(self, expanded, row_group: np.ndarray):
        self.n_groups = int(row_group.max()) + 1 if len(row_group) else 1
        self.keys, inverse = np.unique(expanded.segment * self.n_groups + row_group, return_inverse=True)
        inverse = inverse.reshape(-1)
        self.samples = np.bincount(inverse, minlength=len(self.keys))
        self.theta = bin_counts(inverse, angle_bins(expanded.theta), len(self.keys))
        self.phi = bin_counts(inverse, angle_bins(expanded.phi), len(self.keys))

    def of(self, segments: np.ndarray, groups: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(samples, θ counts, φ counts) that scene groups ``groups`` put into ``segments`` (0 where none)."""
        key = np.asarray(segments) * self.n_groups + np.asarray(groups)
        i = np.minimum(np.searchsorted(self.keys, key), max(len(self.keys) - 1, 0))
        hit = (np.asarray(segments) >= 0) & (self.keys[i] == key) if len(self.keys) else np.zeros(len(key), bool)
        return (np.where(hit, self.samples[i], 0), np.where(hit[:, None], self.theta[i], 0.0),
                np.where(hit[:, None], self.phi[i], 0.0))


def _segments_as_unseen(priors, pairs, stat: dict, pair_group: np.ndarray, own: _GroupCounts) -> np.ndarray:
    """For each pair: the segment the engine would read for the pair's category next to its reference if the
    pair's own scene group were unseen — :meth:`~scenesuggest.learning.priors.Priors.pair_segments`, then, with the
    group's samples left out, all room types for a category seen next to it in this room type only in its own
    group, and every category for one seen at a wall fewer than MIN_OBSERVATIONS times."""
    memo: dict[tuple, int] = {}

    def segment(entity: int, *key) -> int:
        if (entity, *key) not in memo:
            memo[(entity, *key)] = int(priors.pair_segments([entity], *key)[0])
        return memo[(entity, *key)]

    seg = np.array([segment(stat[p.category], p.ref_category, p.scene_type, p.relation, p.surface_type)
                    for p in pairs], dtype=np.int64)
    samples, theta, _ = own.of(seg, pair_group)
    any_s = len(priors.scene_types) - 1
    pooled = priors.entity_index[POOLED]
    for k, p in enumerate(pairs):
        if seg[k] < 0:
            continue
        if p.relation == "wall":
            if priors.seg_theta_n[seg[k]].sum() - theta[k].sum() < MIN_OBSERVATIONS:
                seg[k] = segment(pooled, p.ref_category, p.scene_type, p.relation, p.surface_type)
        elif priors.seg_count[seg[k]] - samples[k] <= 0 and priors.group_keys[priors.seg_group[seg[k]]][1] != any_s:
            seg[k] = segment(stat[p.category], p.ref_category, None, p.relation, p.surface_type)
    return seg


TRUSTS = ("learned", "equal")


def _canonical_evidence(priors, supports, heading: np.ndarray, group: np.ndarray, stat: dict, t: np.ndarray,
                        expand: dict[str, list[int]]) -> np.ndarray:
    """(n, BINS) ``canonical`` log-probabilities over absolute headings (rad), the own scene group left out."""
    n = len(supports)
    f = np.array([FACES.index(s.face) for s in supports])
    alpha_bin = angle_bins(np.array([s.alpha for s in supports]))
    own: dict[tuple[int, int, int, int], np.ndarray] = {}
    for j, s in enumerate(supports):
        if alpha_bin[j] >= 0:
            for e in expand[s.category]:
                own.setdefault((e, t[j], f[j], group[j]), np.zeros(BINS))[alpha_bin[j]] += 1
    e_i = np.array([stat[s.category] for s in supports], dtype=np.int64)
    counts = priors.alpha_n[e_i, t, f].astype(float)
    for i in range(n):
        counts[i] -= own.get((e_i[i], t[i], f[i], group[i]), 0.0)
    alpha = np.array([s.alpha for s in supports], dtype=float)
    ok = np.isfinite(alpha)
    evidence = np.zeros((n, BINS))
    evidence[ok] = turned(log_density(counts[ok]), (heading - alpha)[ok])
    return evidence


def _add_reference_evidence(features: np.ndarray, priors, pairs, expanded, scene_groups: list[int], stat: dict,
                            heading: np.ndarray) -> None:
    """Add the references' θ, φ log-probabilities (rad) into features (n, KINDS, BINS), own scene group left out."""
    n = len(features)
    own = _GroupCounts(expanded, np.array([scene_groups[p.scene] for p in pairs], dtype=np.int64)[expanded.pair])
    pair_group = np.array([scene_groups[p.scene] for p in pairs], dtype=np.int64)
    seg = _segments_as_unseen(priors, pairs, stat, pair_group, own)
    support = np.array([p.support for p in pairs], dtype=np.int64)
    found = seg >= 0
    for angle_name, all_counts, slot in (("theta", priors.seg_theta_n, 0), ("phi", priors.seg_phi_n, 1)):
        rel = np.array([getattr(p, angle_name) for p in pairs], dtype=float)
        kinds = np.array([_or_minus_one(pair_kind_rows(p.relation, p.radial)[slot]) for p in pairs],
                         dtype=np.int64)
        idx = np.flatnonzero(found & np.isfinite(rel) & np.isfinite(heading[support]) & (kinds >= 0))
        if not len(idx):
            continue
        c = all_counts[seg[idx]].astype(float) - own.of(seg[idx], pair_group[idx])[1 + slot]
        values = turned(log_density(c), heading[support[idx]] - rel[idx])
        for k in np.unique(kinds[idx]):
            m = kinds[idx] == k
            features[:, k] += mean_by(support[idx[m]], values[m], n)


def learn_orientation(priors, supports, pairs, expanded, scene_groups: list[int], expand: dict[str, list[int]],
                      kinds: tuple[str, ...] = KINDS, trust: str = "learned") -> np.ndarray:
    """Weights (entities, surface types, KINDS) of the orientation evidence, learned from the training corpus
    with every feature computed as if the object's own scene group (a scene and its near-copies) were unseen.

    Ablations: only ``kinds`` are used (the others get weight 0); ``trust = "equal"`` gives each used kind
    weight 1 everywhere (a plain product of experts, nothing learned)."""
    unknown = set(kinds) - set(KINDS)
    if unknown or trust not in TRUSTS:
        raise ValueError(f"unknown orientation kinds {sorted(unknown)} or trust {trust!r}")
    used = np.array([k in kinds for k in KINDS], dtype=float)
    if trust == "equal":
        return np.broadcast_to(used.astype(np.float32), (len(priors.entities), len(SURFACE_TYPES), len(KINDS))).copy()
    heading = np.array([s.heading for s in supports], dtype=float)
    usable = np.flatnonzero(np.isfinite(heading))
    n = len(supports)
    group = np.array([scene_groups[s.scene] for s in supports], dtype=np.int64)
    stat = {c: priors.stat_entity(c) for c in {s.category for s in supports}}
    features = np.zeros((n, len(KINDS), BINS))
    t = np.array([SURFACE_TYPES.index(s.surface_type) for s in supports])
    features[:, 0] = _canonical_evidence(priors, supports, heading, group, stat, t, expand)
    if pairs:
        _add_reference_evidence(features, priors, pairs, expanded, scene_groups, stat, heading)

    chains = [expand[supports[i].category] for i in usable]
    parent_of = {}
    for chain in expand.values():
        for a, b in zip(chain, chain[1:], strict=False):
            parent_of[a] = b
    canonical = heading - np.array([s.alpha for s in supports], dtype=float)
    canonical = np.where(np.isfinite(canonical), canonical, heading)
    features *= used[None, :, None]
    weights = fit_weights(features[usable], heading[usable], canonical[usable], chains, t[usable],
                          len(priors.entities), len(SURFACE_TYPES), parent_of)
    return used.astype(np.float32) * weights
