"""The straightforward way to answer a context query, the yardstick of the engine's vectorised scorer.

One category at a time and one reference at a time: the occurrence and surface terms read from the priors,
each relative-position density is a ``scipy.stats.gaussian_kde`` (bandwidths fixed to the engine's, scaled to the
engine's peak normalisation), and the learned orientation score is summed bin by bin from the raw histograms.
It computes exactly what :meth:`scenesuggest.suggest.Engine.score` and the engine's learned heading scores
compute — a test holds the two equal — only without any vectorisation. Used by ``bench_suggest.py`` (speed-up)
and ``tests/test_naive_scorer.py`` (equality).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import gaussian_kde

from scenesuggest import poses
from scenesuggest.observations import WALL, bearing, is_radial, near_wall, wall_heading
from scenesuggest.orientation import BINS, KINDS, PSEUDO_COUNT, pair_kind_rows
from scenesuggest.priors import FACES, K_MAX
from scenesuggest.scene import SURFACE_TYPES
from scenesuggest.taxonomy import MIN_OBSERVATIONS


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
        self.priors = engine.priors
        self.kdes: dict[int, FixedKDE] = {}

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
        table = p.occurrence_table(prep.parent_category, prep.scene_type, e.options.backoff)
        any_s = len(p.scene_types) - 1
        if table is None:
            mask = np.broadcast_to(p.borrowed(np.array([entity]), any_s, prep.scene_type), (1,))
            return float(e.base_rate[i]) * float(mask[0])
        k = sum(entity in p.entity_chain(child.category) for child in prep.query.scene.children(prep.query.parent_id))
        return float(table[entity, min(k, K_MAX)]) * float(e.share[i])

    def scores(self, query) -> np.ndarray:
        """The total score of every candidate: λ1 · occurrence · surface + λ2 · Σ_r P_relpos."""
        e, p = self.engine, self.priors
        prep = e.prepare(query)
        t = SURFACE_TYPES.index(prep.surface_type)
        out = np.zeros(len(e.candidates))
        for i in range(len(e.candidates)):
            position = 0.0
            for ref, relation in prep.references:
                segments, trusts = p.pair_sources(e.stat_entity[i:i + 1], ref.category, prep.scene_type, relation,
                                                  prep.surface_type, e.options.backoff)
                if segments[0] >= 0:
                    delta = poses.plane_offset(prep.point, prep.normal, ref.transform, is_radial(ref.size))
                    position += self.density(int(segments[0]), delta) * float(e.share[i]) * float(trusts[0])
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
            segment = int(p.pair_segments([entity], ref.category if ref else WALL, prep.scene_type, relation,
                                          prep.surface_type, e.options.backoff)[0])
            if ref is None and (segment < 0 or p.seg_theta_n[segment].sum() < MIN_OBSERVATIONS):
                segment = p.pooled_segment(WALL, prep.scene_type, relation, prep.surface_type)
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
