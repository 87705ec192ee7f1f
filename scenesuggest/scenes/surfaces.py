"""Surface types of support contacts and attachment faces, from boxes alone.

A contact is a point on the parent's surface with the surface normal there (pointing away from the
parent's material, towards the child). Its *surface type* is the direction of that normal
(``up`` / ``down`` / ``vertical``, split at 45°) and its *side*: ``exterior`` when the point lies on the
parent's bbox face that the normal points out of (a desk top), ``interior`` when the normal points into
the parent's box (a room's floor and walls, a shelf inside a bookcase). The child's *attachment face* is
the face of its own bbox whose outward normal is closest to the opposite of the contact normal.
"""

from __future__ import annotations

import numpy as np

from . import frames

#: |n·up| above this is a horizontal surface (45°).
HORIZONTAL_COS = np.cos(np.radians(45.0))
#: A contact within this fraction of the parent's extent (plus 1 cm) of its outer face is on the outside.
EXTERIOR_FRACTION = 0.1
EXTERIOR_SLACK_M = 0.01


def surface_direction(normal) -> str:
    """``up``, ``down`` or ``vertical`` for a world-frame surface normal."""
    n = np.asarray(normal, dtype=float)
    y = n[1] / (np.linalg.norm(n) or 1.0)
    if y > HORIZONTAL_COS:
        return "up"
    if y < -HORIZONTAL_COS:
        return "down"
    return "vertical"


def surface_side(parent_transform: np.ndarray, parent_size, point, normal) -> str:
    """``interior`` or ``exterior`` of a contact on a parent box (see the module docstring)."""
    p = frames.apply(np.linalg.inv(parent_transform), np.asarray(point, dtype=float)[None])[0]
    n = frames.direction_in_frame(parent_transform, np.asarray(normal, dtype=float)[None])[0]
    axis = int(np.argmax(np.abs(n)))
    size = np.asarray(parent_size, dtype=float)
    lo = np.array([-size[0] / 2, 0.0, -size[2] / 2])
    hi = np.array([size[0] / 2, size[1], size[2] / 2])
    outer = hi[axis] if n[axis] > 0 else lo[axis]
    slack = EXTERIOR_FRACTION * size[axis] + EXTERIOR_SLACK_M
    return "exterior" if abs(p[axis] - outer) <= slack else "interior"


def surface_type(parent_transform: np.ndarray, parent_size, point, normal) -> str:
    """``{direction}_{side}``, e.g. ``up_exterior`` for a desk top, ``vertical_interior`` for a wall."""
    return f"{surface_direction(normal)}_{surface_side(parent_transform, parent_size, point, normal)}"


def attachment_face(child_transform: np.ndarray, normal) -> str:
    """The child's bbox face that touches a surface with world normal ``normal``."""
    n_local = frames.direction_in_frame(child_transform, -np.asarray(normal, dtype=float)[None])[0]
    return frames.face_of_direction(n_local)
