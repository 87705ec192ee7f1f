"""Poses on support surfaces: attaching a face to a plane, headings within the plane, plane coordinates.

A placement attaches face ``F`` of an object's canonical bbox to a surface with world normal ``n`` and
then turns it by an angle α about ``n``::

    R = R_n(α) · R_attach(F, n),   T = translate(point) · R · translate(−centre of F)

Headings are angles (radians) about ``n`` measured from the plane's zero direction: world +Z on
horizontal planes (floors, table tops, ceilings), world +Y (up) on vertical ones (walls). An object's
heading is that of its in-plane reference vector ``v_F`` (its front +Z when it stands on its bottom or
hangs by its top, its up +Y when attached by a side), so on a floor the heading is the yaw of the front.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from . import frames
from .surfaces import HORIZONTAL_COS

#: In-plane reference vector of each attachment face (canonical frame), orthogonal to its normal.
FACE_REFERENCE = {
    "bottom": (0.0, 0.0, 1.0), "top": (0.0, 0.0, 1.0),
    "front": (0.0, 1.0, 0.0), "back": (0.0, 1.0, 0.0), "left": (0.0, 1.0, 0.0), "right": (0.0, 1.0, 0.0),
}
UP = np.array([0.0, 1.0, 0.0])


def is_horizontal(normal) -> bool:
    n = np.asarray(normal, dtype=float)
    return abs(n[1]) / (np.linalg.norm(n) or 1.0) > HORIZONTAL_COS


#: Centre of each face of a canonical bbox as a fraction of its size (bottom centred at the origin).
FACE_CENTRE = {
    "bottom": (0.0, 0.0, 0.0), "top": (0.0, 1.0, 0.0), "front": (0.0, 0.5, 0.5), "back": (0.0, 0.5, -0.5),
    "left": (0.5, 0.5, 0.0), "right": (-0.5, 0.5, 0.0),
}


def face_centre(face: str, size) -> np.ndarray:
    """Centre of a bbox face in the canonical frame (bottom centred at the origin)."""
    return np.asarray(FACE_CENTRE[face]) * np.asarray(size, dtype=float)


def axis_rotation(axis, angle: float) -> np.ndarray:
    """3×3 right-handed rotation by ``angle`` (radians) about unit ``axis``."""
    x, y, z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    c, s, t = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return np.array([[t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                     [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                     [t * x * z - s * y, t * y * z + s * x, t * z * z + c]])


#: How close to opposite (1 + cos of the angle) a face and a surface may be before the face is turned half round a
#: fixed axis rather than along the shortest arc, which is then undefined (the browser's geometry.js: the same).
OPPOSITE = 1e-8


def attach_rotation(face: str, normal) -> np.ndarray:
    """3×3 rotation taking face ``face``'s outward normal onto −``normal`` (α = 0).

    Between two horizontal directions this is a turn about +Y, so that wall objects stay upright; between opposite
    directions a half turn about +X (a top or bottom face: the object turned over front to back) or +Y (a side
    face: it stays upright); otherwise the shortest arc, computed as a unit quaternion (precise up to opposite,
    as three.js computes it in the browser).
    """
    a = np.asarray(frames.FACE_NORMALS[face], dtype=float)
    b = -np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    if abs(a[1]) < 1e-9 and abs(b[1]) < 1e-6:
        angle = math.atan2(a[2] * b[0] - a[0] * b[2], a[0] * b[0] + a[2] * b[2])
        return frames.rotation_y(angle)[:3, :3]
    if np.dot(a, b) + 1 < OPPOSITE:
        return axis_rotation([1.0, 0.0, 0.0] if abs(a[1]) > 0.5 else [0.0, 1.0, 0.0], math.pi)
    return _shortest_arc(a, b)


def _shortest_arc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3×3 rotation taking unit ``a`` onto unit ``b`` along the shortest arc, from the unit quaternion
    (a × b, 1 + a·b): no division by 1 + a·b, so it stays a rotation to rounding as the two near opposite."""
    q = np.array([*np.cross(a, b), 1.0 + float(np.dot(a, b))])
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def plane_zero(normal) -> np.ndarray:
    """The zero-heading direction of a plane: +Z on horizontal planes, +Y on vertical ones (unit, in-plane)."""
    return plane_axes(normal)[1]


def plane_axes(normals) -> np.ndarray:
    """(…, 3, 3) the unit normal, the zero direction (+Z projected onto the plane on horizontal planes, +Y on
    vertical ones) and their cross product n × zero (a quarter turn on), as rows, of each plane with normal (…, 3)."""
    n = np.asarray(normals, dtype=float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    ref = np.where(np.abs(n[..., 1:2]) > HORIZONTAL_COS, (0.0, 0.0, 1.0), (0.0, 1.0, 0.0))
    z = ref - (ref * n).sum(axis=-1, keepdims=True) * n
    z = z / np.linalg.norm(z, axis=-1, keepdims=True)
    side = np.stack([n[..., 1] * z[..., 2] - n[..., 2] * z[..., 1], n[..., 2] * z[..., 0] - n[..., 0] * z[..., 2],
                     n[..., 0] * z[..., 1] - n[..., 1] * z[..., 0]], axis=-1)  # np.cross is slower on few rows
    return np.stack([n, z, side], axis=-2)


@functools.lru_cache(maxsize=256)
def _plane_axes(normal: tuple[float, float, float]) -> np.ndarray:
    axes = plane_axes(normal)
    axes.setflags(write=False)
    return axes


def headings(directions, normals) -> np.ndarray:
    """(N,) signed angles (radians, about each normal) from the plane's zero direction (see :func:`plane_zero`) to
    each direction projected onto its plane; NaN where a direction is perpendicular to its plane. ``normals``: one
    per direction, or one for all.

    The angle is atan2(d · (n × zero), d · zero) (:func:`plane_axes`): both axes lie in the plane, so the part of
    ``d`` along the normal changes neither."""
    d = np.asarray(directions, dtype=float).reshape(-1, 3)
    normals = np.asarray(normals, dtype=float)
    if normals.size == 3:  # one plane: its axes are memoised (a scene's clicks fall on few distinct planes)
        along = d @ _plane_axes(tuple(normals.reshape(3).tolist())).T  # (N, 3): along n, zero, n × zero
    else:
        along = np.einsum("nj,nij->ni", d, plane_axes(normals.reshape(-1, 3)))
    flat = along[:, 1] ** 2 + along[:, 2] ** 2  # the squared length of d on the plane
    return np.where(flat < 1e-18, np.nan, np.arctan2(along[:, 2], along[:, 1]))


def heading(direction, normal) -> float:
    """Signed angle (radians, about ``normal``) from the plane's zero direction to ``direction`` projected
    onto the plane; NaN when ``direction`` is perpendicular to the plane (:func:`headings` of one)."""
    return float(headings(direction, normal)[0])


def rotation_of(transform: np.ndarray) -> np.ndarray:
    """The rotation part of a transform (columns normalised, scale removed)."""
    r = np.asarray(transform, dtype=float)[:3, :3]
    return r / np.linalg.norm(r, axis=0, keepdims=True)


def object_heading(transform: np.ndarray, face: str, normal) -> float:
    """Heading of an object attached by ``face`` to a plane with ``normal`` (see the module docstring)."""
    return heading(rotation_of(transform) @ np.asarray(FACE_REFERENCE[face]), normal)


def zero_heading(face: str, normal) -> float:
    """Heading of a face attached at α = 0; α = heading − zero_heading."""
    return heading(attach_rotation(face, normal) @ np.asarray(FACE_REFERENCE[face]), normal)


@functools.lru_cache(maxsize=1024)
def _attach_rotation(face: str, normal: tuple[float, float, float]) -> np.ndarray:
    r = attach_rotation(face, normal)
    r.setflags(write=False)
    return r


@functools.lru_cache(maxsize=256)
def _zero_headings(normal: tuple[float, float, float]) -> np.ndarray:
    out = np.nan_to_num([zero_heading(face, normal) for face in frames.FACES])
    out.setflags(write=False)
    return out


def zero_headings(normal) -> np.ndarray:
    """:func:`zero_heading` of every face (in ``frames.FACES`` order) on a plane with ``normal``; 0 where
    undefined. Memoised (read-only): a scene's clicks fall on few distinct planes."""
    return _zero_headings(tuple(np.asarray(normal, dtype=float).reshape(3).tolist()))


def placement(point, normal, face: str, size, alpha: float) -> np.ndarray:
    """4×4 canonical → world transform: ``face`` on the plane at ``point``, turned by ``alpha`` about it."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    r = axis_rotation(n, alpha) @ attach_rotation(face, n)
    return frames.translation(point) @ frames.linear(r) @ frames.translation(-face_centre(face, size))


def axis_rotations(axis, angles) -> np.ndarray:
    """(n, 3, 3) rotations by each of ``angles`` about one unit ``axis`` (Rodrigues' formula)."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    angles = np.asarray(angles, dtype=float)[:, None, None]
    return np.eye(3) + np.sin(angles) * k + (1 - np.cos(angles)) * (k @ k)


def placements(points, normal, faces: list[str], sizes, alphas) -> np.ndarray:
    """(n, 4, 4) :func:`placement` for many objects on one plane, vectorised."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    key = tuple(float(v) for v in n)
    attach = {f: _attach_rotation(f, key) for f in set(faces)}
    r = axis_rotations(n, alphas) @ np.stack([attach[f] for f in faces])
    centres = np.array([FACE_CENTRE[f] for f in faces]) * np.asarray(sizes, dtype=float)
    out = np.tile(np.eye(4), (len(faces), 1, 1))
    out[:, :3, :3] = r
    out[:, :3, 3] = np.asarray(points, dtype=float) - np.einsum("nij,nj->ni", r, centres)
    return out


def rotations_of(transforms) -> np.ndarray:
    """(N, 3, 3) rotation parts of (N, 4, 4) transforms (columns normalised)."""
    r = np.asarray(transforms, dtype=float)[:, :3, :3]
    return r / np.linalg.norm(r, axis=1, keepdims=True)


def in_frames(rotations: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """(N, 3) world ``vectors`` (N or 1, 3) in the frames of ``rotations`` (N or 1, 3, 3): Rᵀ v, one each."""
    return (np.swapaxes(rotations, 1, 2) @ vectors[:, :, None])[:, :, 0]


def plane_offsets(points, normals, ref_transforms, radial) -> np.ndarray:
    """(N, 2) offsets of points from reference objects' origins, in each reference's frame, on the plane; points,
    normals and references are given N times or once.

    Horizontal planes: (x, z) in the reference's frame (or (radius, 0) for references without a front).
    Vertical planes: (distance along the wall, height) relative to the reference.
    """
    t = np.asarray(ref_transforms, dtype=float).reshape(-1, 4, 4)
    r = rotations_of(t)
    n = np.asarray(normals, dtype=float).reshape(-1, 3)
    delta = in_frames(r, np.asarray(points, dtype=float).reshape(-1, 3) - t[:, :3, 3])
    n_local = in_frames(r, n / np.linalg.norm(n, axis=1, keepdims=True))
    flat = np.abs(n_local[:, 1]) > HORIZONTAL_COS
    radius = np.hypot(delta[:, 0], delta[:, 2])
    horizontal = np.where(np.asarray(radial, dtype=bool).reshape(-1, 1), np.column_stack([radius, 0 * radius]),
                          delta[:, [0, 2]])
    length = np.hypot(n_local[:, 2], n_local[:, 0])  # of up × n, the direction along a wall: (n_z, 0, −n_x)
    length = np.where(length > 0, length, 1.0)
    vertical = np.column_stack([delta[:, 0] * (n_local[:, 2] / length) + delta[:, 2] * (-n_local[:, 0] / length),
                                delta[:, 1]])
    return np.where(flat[:, None], horizontal, vertical)


def plane_offset(point, normal, ref_transform: np.ndarray, radial: bool) -> np.ndarray:
    """:func:`plane_offsets` of one point."""
    return plane_offsets(point, normal, ref_transform, radial)[0]


def reference_headings(points, normals, ref_transforms, radial) -> np.ndarray:
    """(N,) headings relative orientation is measured from: a reference's front on horizontal planes (or the
    direction from the point towards it when it has no front); the plane's up (0) on vertical planes; 0 where
    undefined. Points, normals and references are given N times or once."""
    t = np.asarray(ref_transforms, dtype=float).reshape(-1, 4, 4)
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    front = t[:, :3, 2] / np.linalg.norm(t[:, :3, 2], axis=1, keepdims=True)
    direction = np.where(np.asarray(radial, dtype=bool).reshape(-1, 1), t[:, :3, 3] - p, front)
    normals = np.asarray(normals, dtype=float)
    h = np.nan_to_num(headings(direction, normals if normals.size == 3 else normals.reshape(-1, 3)), nan=0.0)
    n = normals.reshape(-1, 3)
    return np.where(np.abs(n[:, 1]) / np.linalg.norm(n, axis=1) > HORIZONTAL_COS, h, 0.0)


def reference_heading(point, normal, ref_transform: np.ndarray, radial: bool) -> float:
    """:func:`reference_headings` of one point."""
    return float(reference_headings(point, normal, ref_transform, radial)[0])


def turn_about(placed: np.ndarray, target: np.ndarray, normal) -> float:
    """Signed turn (radians, about the unit ``normal``, counter-clockwise seen from its tip) that takes the
    orientation ``placed`` to ``target`` (3×3 canonical → world rotations of one object on one surface): what
    a person must turn by after placing it. Measured on the canonical axis that ``target`` holds most nearly
    in the surface plane."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    placed, target = np.asarray(placed, dtype=float), np.asarray(target, dtype=float)
    k = int(np.argmin(np.abs(target.T @ n)))
    a, b = placed[:, k] - np.dot(placed[:, k], n) * n, target[:, k] - np.dot(target[:, k], n) * n
    return math.atan2(float(np.dot(n, np.cross(a, b))), float(np.dot(a, b)))


def wrap(angle):
    """Angles (radians) into [0, 2π)."""
    return np.mod(angle, 2 * math.pi)
