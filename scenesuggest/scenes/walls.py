"""The walls of a room, as references for orientation ("back to the nearest wall").

A wall is a vertical plane seen from inside the room, stored in the floor plane (world x, z; metres): its
inward unit ``normal`` (nx, nz), its ``offset`` (a point p is on the wall when n · p = offset, and in front of
it when n · p > offset), its extent ``along`` the wall (the coordinate (−nz, nx) · p runs from ``along[0]`` to
``along[1]``) and its height range ``height`` (world y).

Where walls come from: a scene may carry them (Stanford rooms: measured from the room model's mesh by
:func:`mesh_walls`; the native JSON format's optional ``walls``); otherwise :func:`room_walls` takes the four
inner faces of the box of the scene's room object (AI2-THOR's synthesised rooms, authored rooms).
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from .scene import ROOM, Scene

#: A mesh face counts as vertical when |n_y| is below this; walls are planes of such faces…
VERTICAL_NY = 0.2
#: …clustered by direction (2°) and offset (5 cm), at least this large, reaching this close to the floor and
#: this high: window reveals, skirting boards and furniture-sized details are not walls.
MIN_AREA_M2 = 1.0
MAX_BOTTOM_M = 0.3
MIN_HEIGHT_M = 1.5
ANGLE_STEP_DEG = 2.0
OFFSET_STEP_M = 0.05
#: A point "faces" a wall when it is no more than this behind it and within this margin of its ends.
BEHIND_M = 0.05
END_MARGIN_M = 0.1


@dataclass(frozen=True)
class Wall:
    """One wall in the floor plane (see the module docstring); metres."""

    normal: tuple[float, float]
    offset: float
    along: tuple[float, float]
    height: tuple[float, float]

    def to_dict(self) -> dict:
        return {"normal": list(self.normal), "offset": self.offset, "along": list(self.along),
                "height": list(self.height)}

    @property
    def heading_normal(self) -> np.ndarray:
        """The inward normal as a world 3-vector."""
        return np.array([self.normal[0], 0.0, self.normal[1]])


def box_walls(lo, hi) -> list[Wall]:
    """The four inner faces of an axis-aligned room box (world min and max corners)."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    h = (float(lo[1]), float(hi[1]))
    return [
        Wall((1.0, 0.0), float(lo[0]), (float(lo[2]), float(hi[2])), h),  # x = lo: along = z
        Wall((-1.0, 0.0), float(-hi[0]), (float(-hi[2]), float(-lo[2])), h),
        Wall((0.0, 1.0), float(lo[2]), (float(-hi[0]), float(-lo[0])), h),  # z = lo: along = −x
        Wall((0.0, -1.0), float(-hi[2]), (float(lo[0]), float(hi[0])), h),
    ]


def room_walls(scene: Scene) -> list[Wall]:
    """The scene's own walls, else the inner faces of its room object's box, else none."""
    if scene.walls is not None:
        return scene.walls
    rooms = [o for o in scene.roots() if o.category == ROOM]
    if not rooms:
        return []
    return box_walls(*rooms[0].world_bbox())


def nearest_wall(walls: list[Wall], point) -> tuple[Wall, float] | None:
    """The nearest wall that ``point`` (world, metres) stands in front of, and its distance; None if none."""
    p = np.asarray(point, dtype=float)[[0, 2]]
    best = None
    for w in walls:
        n = np.asarray(w.normal)
        distance = float(n @ p - w.offset)
        along = float(-n[1] * p[0] + n[0] * p[1])
        if distance < -BEHIND_M or not (w.along[0] - END_MARGIN_M <= along <= w.along[1] + END_MARGIN_M):
            continue
        if best is None or distance < best[1]:
            best = (w, max(distance, 0.0))
    return best


def mesh_walls(vertices: np.ndarray, faces: np.ndarray) -> list[Wall]:
    """Walls of a room mesh given in the world frame: large vertical planes that reach the floor and rise at
    least MIN_HEIGHT_M (see the constants). Both sides of a double-sided wall are kept; :func:`nearest_wall`
    only sees the side a point stands in front of."""
    tri = np.asarray(vertices, dtype=float)[np.asarray(faces)]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(cross, axis=1) / 2
    normal = cross / np.maximum(2 * area, 1e-12)[:, None]
    horizontal = np.linalg.norm(normal[:, [0, 2]], axis=1)
    keep = (np.abs(normal[:, 1]) < VERTICAL_NY) & (area > 0) & (horizontal > 1e-9)
    if not keep.any():
        return []
    floor = float(tri[..., 1].min())
    n2 = normal[keep][:, [0, 2]] / horizontal[keep][:, None]
    angle = np.round(np.degrees(np.arctan2(n2[:, 0], n2[:, 1])) / ANGLE_STEP_DEG) * ANGLE_STEP_DEG
    centre = tri[keep].mean(axis=1)
    offset = np.round((n2 * centre[:, [0, 2]]).sum(axis=1) / OFFSET_STEP_M) * OFFSET_STEP_M
    clusters: dict[tuple[float, float], list[int]] = defaultdict(list)
    for i, key in enumerate(zip(angle.tolist(), offset.tolist(), strict=True)):
        clusters[key].append(i)
    walls = []
    kept_tri, kept_area = tri[keep], area[keep]
    for (deg, off), members in sorted(clusters.items()):
        if kept_area[members].sum() < MIN_AREA_M2:
            continue
        pts = kept_tri[members].reshape(-1, 3)
        bottom, top = float(pts[:, 1].min()), float(pts[:, 1].max())
        if bottom - floor > MAX_BOTTOM_M or top - bottom < MIN_HEIGHT_M:
            continue
        n = (math.sin(math.radians(deg)), math.cos(math.radians(deg)))
        along = -n[1] * pts[:, 0] + n[0] * pts[:, 2]
        walls.append(Wall((round(n[0], 6), round(n[1], 6)), float(off), (float(along.min()), float(along.max())),
                          (bottom, top)))
    return walls
