"""The straightforward way to answer a context query, the yardstick of the engine's vectorised scorer.

One category at a time and one reference at a time: the occurrence and surface terms read from the priors,
each relative-position density is a ``scipy.stats.gaussian_kde`` (bandwidths fixed to the engine's, scaled to the
engine's peak normalisation), and the learned orientation score is summed bin by bin from the raw histograms.
It computes exactly what :meth:`scenesuggest.suggestion.suggest.Engine.score` and the engine's learned heading scores
compute — a test holds the two equal — only without any vectorisation. Used by ``bench_suggest.py`` (speed-up)
and ``tests/engine/suggestion/test_naive_scorer.py`` (equality).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import gaussian_kde

from scenesuggest.learning.observations import POOLED, RELATIONS, WALL, bearing, is_radial, near_wall, wall_heading
from scenesuggest.learning.orientation import BINS, KINDS, PSEUDO_COUNT, pair_kind_rows
from scenesuggest.learning.priors import FACES, K_MAX, UNSEEN_IN_SCENE_TYPE
from scenesuggest.scenes import poses
from scenesuggest.scenes.scene import SURFACE_TYPES
from scenesuggest.scenes.taxonomy import MIN_OBSERVATIONS


class FixedKDE(gaussian_kde):
    """A Gaussian KDE whose kernel is diagonal with the given bandwidths (metres) instead of scaled from the
    data's covariance."""

    def __init__(self, points: np.ndarray, bandwidth: np.ndarray):
        self._bandwidth = np.asarray(bandwidth, dtype=np.float64)
        super().__init__(np.asarray(points, dtype=np.float64).T)

    def _compute_covariance(self):
        self.factor = 1.0
        self.covariance = np.diag(self._bandwidth ** 2)
        self.cho_cov = np.diag(self._bandwidth)
        self.log_det = 2 * np.log(np.diag(self.cho_cov * np.sqrt(2 * math.pi))).sum()


class NaiveScorer:
    """Scores of every candidate of an engine, computed the slow way (KDEs are built on first use and kept)."""

    def __init__(self, engine):
        self.engine = engine
        self.priors = p = engine.priors
        self.kdes: dict[int, FixedKDE] = {}
        # the pair statistics' index, rebuilt from the raw arrays: group key → {child entity: segment}
        self.group_of = {tuple(int(v) for v in key): g for g, key in enumerate(p.group_keys)}
        self.children: dict[int, dict[int, int]] = {}
        for segment, (g, child) in enumerate(zip(p.seg_group.tolist(), p.seg_child.tolist(), strict=True)):
            self.children.setdefault(g, {})[child] = segment

    def segment(self, entity: int, ref_category: str, scene_type, relation: str, surface_type: str
                ) -> tuple[int, float]:
        """(segment, weight) of a candidate entity's statistics next to a reference: the query's room type, else
        all room types — weighted by the soft room-type prior for a category never seen there."""
        p = self.priors
        any_s = len(p.scene_types) - 1
        query_s = p.scene_index.get(scene_type)
        r, t = RELATIONS.index(relation), SURFACE_TYPES.index(surface_type)

        def look(key):
            if key is None:
                return -1
            g = self.group_of.get((key[0], key[1], r, t))
            return -1 if g is None else self.children.get(g, {}).get(entity, -1)

        key = p.keyed_entity(ref_category, scene_type, self.engine.options.backoff)
        if key is None:
            return -1, 0.0
        wide = look(p.keyed_entity(ref_category, None, self.engine.options.backoff))
        if key[1] != any_s and self.group_of.get((key[0], key[1], r, t)) is not None:  # the room type's own
            own = look(key)
            return (own, 1.0) if own >= 0 else (wide, UNSEEN_IN_SCENE_TYPE)
        seen = query_s is None or query_s == any_s or p.occ_parent_n[entity, query_s] > 0
        return wide, 1.0 if seen else UNSEEN_IN_SCENE_TYPE

    def kde(self, segment: int) -> FixedKDE:
        if segment not in self.kdes:
            p = self.priors
            a, n = int(p.seg_start[segment]), int(p.seg_count[segment])
            points = p.pair_xy[a:a + n]
            if n < 3:  # scipy wants more samples than dimensions: the same points twice are the same density
                points = np.vstack([points, points])
            self.kdes[segment] = FixedKDE(points, p.seg_bandwidth[segment])
        return self.kdes[segment]

    def density(self, segment: int, delta: np.ndarray) -> float:
        """The engine's P_relpos (peak-normalised, not yet shared) from scipy's normalised density."""
        p = self.priors
        kde = self.kde(segment)
        bx, by = p.seg_bandwidth[segment].astype(np.float64)
        n = int(p.seg_count[segment])
        return float(kde(delta)[0]) * n * 2 * math.pi * bx * by * float(p.seg_weight[segment])

    def occurrence(self, i: int, prep) -> float:
        e, p = self.engine, self.priors
        entity = int(e.stat_entity[i])
        any_s = len(p.scene_types) - 1
        query_s = p.scene_index.get(prep.scene_type)
        seen = query_s is None or query_s == any_s or p.occ_parent_n[entity, query_s] > 0
        key = p.occurrence_key(prep.parent_category, prep.scene_type, e.options.backoff)
        if key is None:
            return float(e.base_rate[i]) * (1.0 if seen else UNSEEN_IN_SCENE_TYPE)
        k = sum(entity in p.entity_chain(child.category) for child in prep.query.scene.children(prep.query.parent_id))

        def row(block):
            children, rows = p.occurrence_rows(block)
            for child, values in zip(children.tolist(), rows, strict=True):
                if child == entity:
                    return float(values[min(k, K_MAX)])
            return None

        if key % len(p.scene_types) != any_s:
            own = row(key)
            if own is None:
                wide = p.occurrence_key(prep.parent_category, None, e.options.backoff)
                own = UNSEEN_IN_SCENE_TYPE * (row(wide) or 0.0) if wide is not None else 0.0
            return own * float(e.share[i])
        return (row(key) or 0.0) * float(e.share[i]) * (1.0 if seen else UNSEEN_IN_SCENE_TYPE)

    def scores(self, query) -> np.ndarray:
        """The total score of every candidate: λ1 · occurrence · surface + λ2 · Σ_r P_relpos."""
        e = self.engine
        prep = e.prepare(query)
        t = SURFACE_TYPES.index(prep.surface_type)
        out = np.zeros(len(e.candidates))
        for i in range(len(e.candidates)):
            position = 0.0
            for ref, relation in prep.references:
                segment, trust = self.segment(int(e.stat_entity[i]), ref.category, prep.scene_type, relation,
                                              prep.surface_type)
                if segment >= 0:
                    delta = poses.plane_offset(prep.point, prep.normal, ref.transform, is_radial(ref.size))
                    position += self.density(segment, delta) * float(e.share[i]) * trust
            out[i] = (e.options.lambda1 * self.occurrence(i, prep) * float(e.surface_prob[i, t])
                      + e.options.lambda2 * position)
        return out

    @staticmethod
    def log_probabilities(counts: np.ndarray) -> list[float]:
        counts = [float(c) for c in counts]
        n = sum(counts)
        smoothed = [(counts[(b - 1) % BINS] + 2 * counts[b] + counts[(b + 1) % BINS]) / 4 for b in range(BINS)]
        return [math.log((s + PSEUDO_COUNT / BINS) / (n + PSEUDO_COUNT)) for s in smoothed]

    @staticmethod
    def turned(values: list[float], angle: float) -> list[float]:
        shift = angle / (2 * math.pi / BINS)
        s0 = math.floor(shift)
        frac = shift - s0
        return [(1 - frac) * values[(h - s0) % BINS] + frac * values[(h - s0 - 1) % BINS] for h in range(BINS)]

    def heading_scores(self, query, i: int, face: int) -> np.ndarray:
        """The learned log-score of every heading bin of candidate ``i`` attached by face ``face``."""
        e, p = self.engine, self.priors
        prep = e.prepare(query)
        t = SURFACE_TYPES.index(prep.surface_type)
        entity = int(e.stat_entity[i])
        evidence: dict[int, list[list[float]]] = {k: [] for k in range(len(KINDS))}
        zero = poses.zero_heading(FACES[face], prep.normal)
        evidence[0].append(self.turned(self.log_probabilities(p.alpha_n[entity, t, face]),
                                       0.0 if math.isnan(zero) else zero))
        references = [(ref, relation, is_radial(ref.size)) for ref, relation in prep.references]
        if prep.wall is not None and near_wall(prep.wall[1], e.size[i]):
            references.append((None, "wall", False))
        for ref, relation, radial in references:
            segment, _ = self.segment(entity, ref.category if ref else WALL, prep.scene_type, relation,
                                      prep.surface_type)
            if ref is None and (segment < 0 or p.seg_theta_n[segment].sum() < MIN_OBSERVATIONS):
                segment, _ = self.segment(p.entity_index[POOLED], WALL, prep.scene_type, relation, prep.surface_type)
            if segment < 0:
                continue
            front_kind, bearing_kind = pair_kind_rows(relation, radial)
            front = (wall_heading(prep.wall[0], prep.normal) if ref is None else
                     poses.reference_heading(prep.point, prep.normal, ref.transform, radial))
            if front_kind is not None and math.isfinite(front):
                evidence[front_kind].append(self.turned(self.log_probabilities(p.seg_theta_n[segment]), front))
            toward = bearing(prep.point, prep.normal, ref) if bearing_kind is not None else math.nan
            if math.isfinite(toward):
                evidence[bearing_kind].append(self.turned(self.log_probabilities(p.seg_phi_n[segment]), toward))
        weights = p.orient_weights[e.candidates[i], t]
        out = np.zeros(BINS)
        for k, rows in evidence.items():
            for h in range(BINS):
                out[h] += float(weights[k]) * (sum(r[h] for r in rows) / len(rows) if rows else 0.0)
        return out
