"""How far a suggested pose is from the true one, in degrees.

* :func:`front_angle_deg` — the angle between the two fronts (canonical +Z in the world), the paper-era figure;
  blind to turns about the front itself (a picture turned on its wall).
* :func:`pose_error_deg` — the angle of the smallest rotation taking the suggested orientation to the true one,
  among the poses that look the same because the model is rotationally symmetric about its up axis (canonical
  +Y; the period from :mod:`scenesuggest.assets.symmetry`): a vase has no error, a rectangular table at most 90°, a
  chair up to 180°. With period 360 (no symmetry) it is the plain rotation angle; a wrong attachment face costs at least
  the tilt between the two ups.

Both take 4×4 (or 3×3) canonical → world transforms; scale is removed first.
"""

from __future__ import annotations

import math

import numpy as np

from ..scenes.poses import rotation_of


def front_angle_deg(predicted: np.ndarray, truth: np.ndarray) -> float:
    """Angle (degrees, 0..180) between the predicted and the true front."""
    a, b = rotation_of(predicted)[:, 2], rotation_of(truth)[:, 2]
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


def pose_error_deg(predicted: np.ndarray, truth: np.ndarray, period_deg: float = 360.0) -> float:
    """Angle (degrees, 0..180) of the smallest rotation from ``predicted`` to ``truth`` up to turns of the model
    by multiples of ``period_deg`` about its up axis (0: any turn; 360: none)."""
    m = rotation_of(truth).T @ rotation_of(predicted)
    # trace of m · R_y(φ) = (m00 + m22) cos φ + (m20 − m02) sin φ + m11
    a, b, c = m[0, 0] + m[2, 2], m[2, 0] - m[0, 2], m[1, 1]
    if period_deg <= 0:
        trace = c + math.hypot(a, b)
    else:
        turns = np.radians(np.arange(0.0, 360.0 - 1e-9, min(period_deg, 360.0)))
        trace = float(np.max(a * np.cos(turns) + b * np.sin(turns) + c))
    return float(np.degrees(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))))
