"""The paper's wrapped angle histograms: 36 bins of 10°, bin 0 centred on 0. One place for the binning and the
counting that the pair priors (θ, φ) and orientation learning (turns from the canonical pose) share."""

from __future__ import annotations

import math

import numpy as np

BINS = 36


def angle_bins(angles: np.ndarray) -> np.ndarray:
    """The 10° bin of each angle (radians); −1 where it is undefined."""
    angles = np.asarray(angles, dtype=np.float64)
    ok = np.isfinite(angles)
    out = np.full(len(angles), -1, dtype=np.int64)
    out[ok] = np.round(angles[ok] / (2 * math.pi / BINS)).astype(np.int64) % BINS
    return out


def bin_counts(segment: np.ndarray, bins: np.ndarray, n_segments: int) -> np.ndarray:
    """(n_segments, BINS) counts of the defined bins of each segment's rows."""
    ok = bins >= 0
    return np.bincount(segment[ok] * BINS + bins[ok], minlength=n_segments * BINS).reshape(
        n_segments, BINS).astype(np.float32)
