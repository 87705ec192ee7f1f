"""Coordinate frames and 4×4 transforms.

World frame: metres, +Y up, right-handed (glTF / three.js). A model's canonical frame: +Y up, +Z front,
origin at the centre of its bounding-box bottom, metres. Seen from the front of the object, its own
right-hand side is −X (right = front × up), so the bbox face at +X is its ``left``.

Matrices are numpy ``(4, 4)`` arrays acting on column vectors; in JSON they are 16 numbers in
column-major order (three.js ``Matrix4.elements``).
"""

from __future__ import annotations

import math

import numpy as np

#: Outward normal of each attachment face of a bbox in the canonical model frame.
FACE_NORMALS: dict[str, tuple[float, float, float]] = {
    "bottom": (0.0, -1.0, 0.0),
    "top": (0.0, 1.0, 0.0),
    "front": (0.0, 0.0, 1.0),
    "back": (0.0, 0.0, -1.0),
    "left": (1.0, 0.0, 0.0),
    "right": (-1.0, 0.0, 0.0),
}
FACES: tuple[str, ...] = tuple(FACE_NORMALS)

#: Stanford Scene Database world (inches, +Z up) → our world (metres, +Y up): (x, y, z) ↦ (x, z, −y).
INCH = 0.0254
Z_UP_TO_Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])


def from_column_major(values) -> np.ndarray:
    """16 numbers in column-major order → a (4, 4) matrix."""
    a = np.asarray(values, dtype=float)
    if a.shape != (16,):
        raise ValueError(f"expected 16 numbers, got {a.size}")
    return a.reshape(4, 4).T.copy()


def to_column_major(m: np.ndarray) -> list[float]:
    """A (4, 4) matrix → 16 Python floats in column-major order."""
    return [float(v) for v in np.asarray(m, dtype=float).T.reshape(16)]


def translation(t) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = t
    return m


def scaling(s) -> np.ndarray:
    m = np.eye(4)
    m[[0, 1, 2], [0, 1, 2]] = np.broadcast_to(np.asarray(s, dtype=float), (3,))
    return m


def linear(r: np.ndarray) -> np.ndarray:
    """Embed a 3×3 linear map in a 4×4 matrix."""
    m = np.eye(4)
    m[:3, :3] = r
    return m


def rotation_y(angle_rad: float) -> np.ndarray:
    """Rotation about +Y by ``angle_rad`` (right-handed): +Z turns towards +X."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def rotation_between(a, b) -> np.ndarray:
    """The 3×3 rotation taking unit vector ``a`` onto unit vector ``b`` (shortest arc)."""
    a = np.asarray(a, dtype=float) / np.linalg.norm(a)
    b = np.asarray(b, dtype=float) / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1 + 1e-9:  # opposite: turn half way round any axis perpendicular to a
        axis = np.cross(a, [1.0, 0, 0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0, 1.0, 0])
        axis /= np.linalg.norm(axis)
        return 2 * np.outer(axis, axis) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


def alignment(up, front) -> np.ndarray:
    """The 3×3 rotation taking a model's ``up`` to +Y and its ``front`` to +Z.

    ``front`` is orthogonalised against ``up`` first, so slightly skewed metadata still gives a rotation.
    """
    u = np.asarray(up, dtype=float)
    u = u / np.linalg.norm(u)
    f = np.asarray(front, dtype=float)
    f = f - np.dot(f, u) * u
    if np.linalg.norm(f) < 1e-9:
        raise ValueError("front is parallel to up")
    f = f / np.linalg.norm(f)
    r = np.cross(u, f)
    return np.stack([r, u, f])


def apply(m: np.ndarray, points) -> np.ndarray:
    """Apply a 4×4 transform to an (N, 3) array of points."""
    p = np.asarray(points, dtype=float)
    return p @ m[:3, :3].T + m[:3, 3]


def direction_in_frame(m: np.ndarray, vectors) -> np.ndarray:
    """World directions or surface normals (N, 3) in the frame of an object whose canonical → world transform is
    ``m`` (rigid plus uniform scale): ``v @ m[:3, :3]``, the normal map of m⁻¹ (m⁻¹'s inverse transpose is mᵀ),
    re-normalised."""
    v = np.asarray(vectors, dtype=float) @ np.asarray(m, dtype=float)[:3, :3]
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n == 0, 1, n)


def box_corners(size) -> np.ndarray:
    """The 8 corners of a canonical bbox of ``size`` (sx, sy, sz): bottom centred at the origin."""
    sx, sy, sz = size
    xs, ys, zs = (-sx / 2, sx / 2), (0.0, sy), (-sz / 2, sz / 2)
    return np.array([[x, y, z] for x in xs for y in ys for z in zs])


def world_bbox(transform: np.ndarray, size) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned world bbox (min, max) of a canonical box of ``size`` under ``transform``."""
    c = apply(transform, box_corners(size))
    return c.min(axis=0), c.max(axis=0)


def world_bboxes(transforms, sizes) -> tuple[np.ndarray, np.ndarray]:
    """:func:`world_bbox` of many boxes at once: transforms (n, 4, 4), sizes (n, 3) → (min, max), each (n, 3)."""
    t = np.asarray(transforms, dtype=float).reshape(-1, 4, 4)
    size = np.asarray(sizes, dtype=float).reshape(-1, 3)
    corners = _UNIT_CORNERS[None] * size[:, None, :]  # (n, 8, 3)
    world = np.einsum("nij,nkj->nki", t[:, :3, :3], corners) + t[:, None, :3, 3]
    return world.min(axis=1), world.max(axis=1)


#: The corners of the canonical box of size (1, 1, 1), in the order of :func:`box_corners`.
_UNIT_CORNERS = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (0.0, 1.0) for z in (-0.5, 0.5)])


def face_of_direction(direction) -> str:
    """The bbox face whose outward normal is closest to ``direction`` (canonical frame)."""
    d = np.asarray(direction, dtype=float)
    return max(FACES, key=lambda f: float(np.dot(FACE_NORMALS[f], d)))


