"""How long a person takes: the keystroke-level model (Card, Moran & Newell 1980) with Fitts' law for drags.

Time is not slept but simulated: each action costs operator times, list scanning costs per item looked at,
drags follow Fitts' law, and a participant-level speed factor scales them (with a little noise per action).
The events carry these simulated client times, so the analysis sees how long a person would have taken given
what the engine returned.
"""

from __future__ import annotations

import math

import numpy as np

#: Keystroke-level model operators, seconds: K keystroke, P point, B button press or release, M mental preparation.
K, P, B, M = 0.28, 1.1, 0.1, 1.35
FITTS_A, FITTS_B, TARGET_M = 0.2, 0.15, 0.05  # drag time = a + b log2(d / w + 1), s and m
COARSE_DEG = 15.0  # one key press of the turning keys, degrees


def drag_seconds(distance_m: float) -> float:
    """A drag over ``distance_m`` metres: press, move by Fitts' law onto a target of TARGET_M, release."""
    return B + FITTS_A + FITTS_B * math.log2(distance_m / TARGET_M + 1) + B


def turn_seconds(turn_deg: float, tolerance_deg: float) -> float:
    """Turning by key presses: COARSE_DEG steps, then (after thinking about it) one degree per press for what
    remains beyond ``tolerance_deg``."""
    coarse = round(abs(turn_deg) / COARSE_DEG)
    fine = abs(abs(turn_deg) - coarse * COARSE_DEG)
    return K * coarse + (M + K * round(fine) if fine > tolerance_deg else 0.0)


class Clock:
    """A participant's clock in one trial: client time (ms since the epoch, as events carry it) and the
    simulated seconds spent, each action scaled by the person's ``speed`` (1 = the model's average person)."""

    def __init__(self, rng: np.random.Generator, speed: float, start_ms: float):
        self.rng, self.speed = rng, speed
        self.ms = start_ms
        self.elapsed = 0.0

    def spend(self, seconds: float) -> None:
        spent = seconds * self.speed * float(self.rng.lognormal(0.0, 0.15))
        self.ms += spent * 1000.0
        self.elapsed += spent
