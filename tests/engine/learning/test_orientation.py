"""The orientation prior's pieces: log-densities, turning histograms, the decision, and learned trust."""

import math

import numpy as np
import pytest

from scenesuggest.learning.orientation import BINS, KINDS, decide, fit_weights, heading_bin, log_density, smooth, turned


def test_log_density_is_a_smoothed_distribution_that_little_data_barely_moves():
    counts = np.zeros(BINS)
    counts[9] = 40
    p = np.exp(log_density(counts))
    assert p.sum() == pytest.approx(1.0) and int(np.argmax(p)) == 9 and p[8] == pytest.approx(p[10])
    one = np.exp(log_density(np.eye(BINS)[9]))
    assert one.max() / one.min() < 8 < p.max() / p.min()  # one observation is weak evidence
    assert np.allclose(log_density(np.zeros(BINS)), -math.log(BINS))


def test_turned_reindexes_to_absolute_headings_with_interpolation():
    values = np.arange(BINS, dtype=float)
    assert turned(values, 0.0)[5] == 5.0
    assert turned(values, math.radians(30))[5] == pytest.approx(2.0)  # out[h] = values[h − 3 bins]
    assert turned(values, math.radians(35))[5] == pytest.approx(1.5)
    rows = turned(np.vstack([values, values]), np.radians([0, 10]))
    assert rows[0, 7] == 7 and rows[1, 7] == 6


def test_turned_and_smooth_agree_with_their_definitions_bin_by_bin():
    rng = np.random.default_rng(3)
    values = rng.normal(size=(4, 3, BINS))
    angles = rng.uniform(-20.0, 20.0, size=(4, 3))  # radians: negative and several turns
    out = turned(values, angles)
    assert out.shape == values.shape
    for i, j in np.ndindex(4, 3):
        shift = angles[i, j] / math.radians(360 / BINS)
        whole, frac = math.floor(shift), shift - math.floor(shift)
        for h in range(BINS):
            expected = (1 - frac) * values[i, j, (h - whole) % BINS] + frac * values[i, j, (h - whole - 1) % BINS]
            assert out[i, j, h] == pytest.approx(expected, abs=1e-12)
    assert np.array_equal(turned(values[0, 0], angles[0, 0]), out[0, 0])  # one row as it is within many
    counts = rng.integers(0, 9, size=(5, BINS)).astype(float)
    kernel = (np.roll(counts, 1, axis=1) + 2 * counts + np.roll(counts, -1, axis=1)) / 4
    assert np.array_equal(smooth(counts), kernel) and np.array_equal(smooth(counts[0]), kernel[0])


def test_the_canonical_heading_is_kept_unless_another_heading_stands_out():
    flat = np.zeros((1, BINS))
    heading, kept = decide(flat, [math.radians(20)])
    assert kept[0] and heading[0] == pytest.approx(math.radians(20))
    peaked = np.full((1, BINS), -5.0)
    peaked[0, 27] = 0.0
    heading, kept = decide(peaked, [0.0])
    assert not kept[0] and heading[0] == pytest.approx(math.radians(270))
    near_tie = np.zeros((1, BINS))
    near_tie[0, 27], near_tie[0, 0] = 0.1, 0.0
    assert decide(near_tie, [0.0])[1][0]  # canonical holds most of the best one's mass


def test_trust_goes_to_the_kind_of_evidence_that_predicts_held_out_headings():
    rng = np.random.default_rng(0)
    n = 300
    truth = rng.uniform(0, 2 * math.pi, n)
    features = np.zeros((n, len(KINDS), BINS))
    sharp = np.zeros(BINS)
    sharp[0] = 30
    for i in range(n):
        features[i, KINDS.index("sibling_bearing")] = turned(log_density(sharp), truth[i])  # points at the truth
        features[i, KINDS.index("wall")] = turned(log_density(sharp), rng.uniform(0, 2 * math.pi))  # noise
    canonical = rng.uniform(0, 2 * math.pi, n)
    weights = fit_weights(features, truth, canonical, [[0]] * n, np.zeros(n, dtype=int), 1, 6, {})
    w = weights[0, 0]
    assert w[KINDS.index("sibling_bearing")] > 0.5 and w[KINDS.index("wall")] < 0.1
    score = np.einsum("k,nkb->nb", w, features)
    predicted, _ = decide(score, canonical)
    assert np.mean(heading_bin(predicted) == heading_bin(truth)) > 0.9
    # the switch: when the fitted weights do not beat the canonical heading (here it is the truth itself), they
    # are replaced by zeros and the canonical heading is kept
    useless = fit_weights(features[:, [KINDS.index("wall")]] * 1.0, truth, truth, [[0]] * n,
                          np.zeros(n, dtype=int), 1, 6, {})
    assert np.all(useless == 0)
