"""How close a scene came to its target: the paper's task is to recreate the target, so a trial is scored.

The objects scored are those the participant had to place: the target's objects that are not in the trial's
start scene, against the scene's objects that are not in it either. They are matched one to one by an
assignment (Hungarian, :func:`scipy.optimize.linear_sum_assignment`) that first maximises how well the categories
agree — the same category (credit 1) before a category that shares the target's taxonomy parent or is its parent
or child (credit :data:`BACKOFF_CREDIT`); other categories are never matched — and then minimises the distance.
For each matched pair:

- the position error: the distance between the two objects' origins (the centre of the bounding box's bottom,
  world frame), metres;
- the orientation error: the angle of the smallest rotation between the two orientations, up to the turns about
  the target model's up axis that its rotational symmetry makes invisible
  (:func:`scenesuggest.contract.pose_error.pose_error_deg`), degrees;
- its quality ``q = category credit × position credit × orientation credit``, where the position credit is 1 up
  to :data:`POSITION_FULL_M`, falls linearly to 0 at :data:`POSITION_NONE_M`, and the orientation credit likewise
  from :data:`ORIENTATION_FULL_DEG` to :data:`ORIENTATION_NONE_DEG`.

The score is ``Σ q / (target objects + extra objects)`` in [0, 1]: 1 when every target object is there in its
category, within 5 cm and 10°, and nothing else was added; an object of the target that is missing or an extra
one counts as a zero.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from .pose_error import pose_error_deg

POSITION_FULL_M, POSITION_NONE_M = 0.05, 0.5
ORIENTATION_FULL_DEG, ORIENTATION_NONE_DEG = 10.0, 90.0
BACKOFF_CREDIT = 0.5
#: How the assignment weighs category agreement against distance: a category step outweighs any distance.
_CATEGORY_COST_M = 1000.0
FORMULA = (f"score = Σ q / (target objects + extra objects); per matched pair q = category credit (1 same "
           f"category, {BACKOFF_CREDIT} a category sharing its taxonomy parent, or its parent or child) × position "
           f"credit (1 within {POSITION_FULL_M * 100:g} cm, falling linearly to 0 at {POSITION_NONE_M * 100:g} "
           "cm) × orientation "
           f"credit (1 within {ORIENTATION_FULL_DEG:g}°, falling linearly to 0 at {ORIENTATION_NONE_DEG:g}°, the "
           "angle folded by the model's rotational symmetry); objects matched one to one by category, then by "
           "distance (Hungarian)")


@dataclass(frozen=True)
class Match:
    target: str
    placed: str
    category_credit: float
    position_error_m: float
    orientation_error_deg: float
    quality: float


@dataclass(frozen=True)
class Closeness:
    """A scene against its target: the score, the matched pairs, and the ids of the missing and extra objects."""

    score: float
    matches: tuple[Match, ...]
    missing: tuple[str, ...]
    extra: tuple[str, ...]

    @property
    def position_error_m(self) -> float:
        """Mean position error of the matched objects (NaN when none matched)."""
        return float(np.mean([m.position_error_m for m in self.matches])) if self.matches else float("nan")

    @property
    def orientation_error_deg(self) -> float:
        """Mean orientation error of the matched objects (NaN when none matched)."""
        return float(np.mean([m.orientation_error_deg for m in self.matches])) if self.matches else float("nan")

    def record(self) -> dict:
        """:meth:`to_dict` as JSON can hold it: the mean errors None (not NaN) when nothing matched."""
        return {k: None if isinstance(v, float) and v != v else v for k, v in self.to_dict().items()}

    def to_dict(self) -> dict:
        return {"score": self.score, "matched": len(self.matches), "missing": len(self.missing),
                "extra": len(self.extra), "position_error_m": self.position_error_m,
                "orientation_error_deg": self.orientation_error_deg,
                "matches": [asdict(m) for m in self.matches]}


def category_credit(placed: str, target: str, parent_of: Callable[[str], str | None]) -> float:
    """1 for the same category, :data:`BACKOFF_CREDIT` for a category that shares the target's taxonomy parent
    or is its parent or child, else 0."""
    if placed == target:
        return 1.0
    a, b = parent_of(placed), parent_of(target)
    if b is not None and (a == b or placed == b) or a is not None and a == target:
        return BACKOFF_CREDIT
    return 0.0


def _credit(error: float, full: float, none: float) -> float:
    return float(np.clip((none - error) / (none - full), 0.0, 1.0))


def _matrix(o: dict) -> np.ndarray:
    return np.asarray(o["transform"], dtype=float).reshape(4, 4).T


def closeness(scene: Iterable[dict], target: Iterable[dict], start_ids: Iterable[str],
              parent_of: Callable[[str], str | None], period_of: Callable[[str], float]) -> Closeness:
    """Score ``scene``'s objects (as a scene file lists them) against ``target``'s, leaving out ``start_ids``
    (the objects of the trial's start scene). ``parent_of`` gives a category's taxonomy parent, ``period_of`` a
    model's symmetry period (degrees about its up axis; 360: none)."""
    start = set(start_ids)
    placed = [o for o in scene if o["id"] not in start]
    wanted = [o for o in target if o["id"] not in start]
    if not wanted and not placed:
        return Closeness(1.0, (), (), ())
    credit = np.array([[category_credit(p["category"], t["category"], parent_of) for p in placed] for t in wanted])
    credit = credit.reshape(len(wanted), len(placed))
    origins_t = np.array([_matrix(t)[:3, 3] for t in wanted]).reshape(-1, 3)
    origins_p = np.array([_matrix(p)[:3, 3] for p in placed]).reshape(-1, 3)
    distance = np.linalg.norm(origins_t[:, None, :] - origins_p[None, :, :], axis=2)
    cost = np.where(credit > 0, (1.0 - credit) * _CATEGORY_COST_M + distance, np.inf)
    finite = np.where(np.isfinite(cost), cost, 1e12)
    rows, cols = linear_sum_assignment(finite) if cost.size else (np.array([], int), np.array([], int))
    matches = []
    for i, j in zip(rows, cols, strict=True):
        if not np.isfinite(cost[i, j]):
            continue
        t, p = wanted[i], placed[j]
        angle = pose_error_deg(_matrix(p), _matrix(t), period_of(t["model_id"]))
        quality = credit[i, j] * _credit(distance[i, j], POSITION_FULL_M, POSITION_NONE_M) \
            * _credit(angle, ORIENTATION_FULL_DEG, ORIENTATION_NONE_DEG)
        matches.append(Match(t["id"], p["id"], float(credit[i, j]), float(distance[i, j]), angle, float(quality)))
    matched_t, matched_p = {m.target for m in matches}, {m.placed for m in matches}
    missing = tuple(t["id"] for t in wanted if t["id"] not in matched_t)
    extra = tuple(p["id"] for p in placed if p["id"] not in matched_p)
    score = sum(m.quality for m in matches) / (len(wanted) + len(extra))
    return Closeness(float(score), tuple(matches), missing, extra)
