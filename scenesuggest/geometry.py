"""Geometry on meshes and scenes: support surfaces of a model, and ray casting with surface-hit classification.

Frames: a model's mesh is in its canonical frame (metres, +Y up); a scene is in the world frame.
Ray casting merges the whole scene into one mesh (one intersection structure, trimesh with rtree) and
keeps a face → object index; objects without a mesh are represented by their oriented bounding boxes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trimesh

from . import surfaces
from .scene import ObjectInstance, Scene

#: A face is part of a support surface when its normal is within ~18° of +Y.
UPWARD_COS = 0.95
#: Faces whose heights differ by less than this (metres) lie in one plane.
PLANE_TOLERANCE_M = 0.01
#: A horizontal face supports things when nothing of the model lies within this distance above it.
CLEARANCE_M = 0.05
FLIPPED_CLEARANCE_M = 0.3
RAY_LIFT_M = 1e-4


@dataclass(frozen=True)
class SupportSurface:
    """A horizontal, upward-facing patch of a model: its height, area and footprint (canonical frame, m)."""

    height: float
    area: float
    footprint_min: tuple[float, float]  # (x, z)
    footprint_max: tuple[float, float]
    side: str  # "exterior" on top of the model's box, "interior" inside it (a shelf in a bookcase)

    def to_dict(self) -> dict:
        return {"height": self.height, "area": self.area, "footprint_min": list(self.footprint_min),
                "footprint_max": list(self.footprint_max), "side": self.side}


def _as_mesh(model: trimesh.Trimesh | trimesh.Scene) -> trimesh.Trimesh:
    if isinstance(model, trimesh.Scene):
        parts = [g for g in model.dump() if isinstance(g, trimesh.Trimesh)]
        return trimesh.util.concatenate(parts)
    return model


def _upward_faces(mesh: trimesh.Trimesh) -> np.ndarray:
    """Horizontal faces with free space above them, judged by a ray up from each face as well as by its
    winding, because 3D Warehouse meshes wind faces either way."""
    flat = np.flatnonzero(np.abs(mesh.face_normals[:, 1]) > UPWARD_COS)
    if not len(flat):
        return flat
    # one of each set of coincident faces (3D Warehouse meshes often hold each face twice)
    keys = np.round(np.sort(mesh.triangles[flat].reshape(len(flat), -1), axis=1), 5)
    _, first = np.unique(keys, axis=0, return_index=True)
    flat = flat[np.sort(first)]
    origins = mesh.triangles_center[flat] + [0.0, RAY_LIFT_M, 0.0]
    directions = np.tile([0.0, 1.0, 0.0], (len(flat), 1))
    locations, rays, _ = mesh.ray.intersects_location(origins, directions, multiple_hits=False)
    gap = np.full(len(flat), np.inf)
    np.minimum.at(gap, rays, locations[:, 1] - origins[rays, 1])
    # a face wound downwards may be a flipped top, or the underside of a thick board: ask for more room
    needed = np.where(mesh.face_normals[flat, 1] > 0, CLEARANCE_M, FLIPPED_CLEARANCE_M)
    return flat[gap >= needed]


def support_surfaces(model: trimesh.Trimesh | trimesh.Scene, min_area: float = 0.005) -> list[SupportSurface]:
    """Upward faces clustered into planes (by height), split into connected patches of at least
    ``min_area`` square metres, largest first."""
    mesh = _as_mesh(model)
    top = float(mesh.bounds[1][1])
    height_of_box = float(np.ptp(mesh.bounds[:, 1])) or 1.0
    up = _upward_faces(mesh)
    if not len(up):
        return []
    heights = mesh.triangles_center[up, 1]
    order = np.argsort(heights)
    breaks = np.flatnonzero(np.diff(heights[order]) > PLANE_TOLERANCE_M) + 1
    out = []
    for group in np.split(up[order], breaks):
        patch = mesh.submesh([group], append=True, repair=False)
        patch.merge_vertices()
        for piece in patch.split(only_watertight=False):
            if piece.area < min_area:
                continue
            lo, hi = piece.bounds
            h = float(np.average(piece.triangles_center[:, 1], weights=piece.area_faces))
            side = "exterior" if top - h <= surfaces.EXTERIOR_FRACTION * height_of_box + surfaces.EXTERIOR_SLACK_M \
                else "interior"
            out.append(SupportSurface(h, float(piece.area), (float(lo[0]), float(lo[2])),
                                      (float(hi[0]), float(hi[2])), side))
    return sorted(out, key=lambda s: -s.area)


@dataclass(frozen=True)
class SurfaceHit:
    """Where a ray met a scene: the object, the world point and normal (facing the ray), the surface type."""

    object_id: str
    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    surface_type: str
    distance: float

    def to_dict(self) -> dict:
        return {"object_id": self.object_id, "point": list(self.point), "normal": list(self.normal),
                "surface_type": self.surface_type, "distance": self.distance}


def classify_hit(scene: Scene, object_id: str, point, normal) -> str:
    """Surface type (``up_exterior`` …) of a point on an object with the given world normal."""
    o = scene.objects[object_id]
    return surfaces.surface_type(o.transform, o.size, point, normal)


def box_mesh(size) -> trimesh.Trimesh:
    """The canonical bbox of ``size`` as a mesh (bottom centred at the origin)."""
    m = trimesh.creation.box(extents=np.asarray(size, dtype=float))
    m.apply_translation([0, size[1] / 2, 0])
    return m


MeshSource = Callable[[ObjectInstance], trimesh.Trimesh | trimesh.Scene | None]


class SceneRaycaster:
    """Ray casting against every object of a scene at once.

    ``meshes`` gives an object's mesh in its canonical frame (e.g. loaded from the model library);
    when it returns None, or is not given, the object's bbox stands in for it.
    """

    def __init__(self, scene: Scene, meshes: MeshSource | None = None):
        self.scene = scene
        parts, owners = [], []
        for o in scene:
            model = meshes(o) if meshes else None
            mesh = _as_mesh(model).copy() if model is not None else box_mesh(o.size)
            mesh.apply_transform(o.transform)
            parts.append(mesh)
            owners.append(np.full(len(mesh.faces), len(owners)))
        self._ids = [o.id for o in scene]
        self._mesh = trimesh.util.concatenate(parts)
        self._owner = np.concatenate(owners)

    def cast(self, origins, directions) -> list[SurfaceHit | None]:
        """The first hit of each ray (None where a ray hits nothing)."""
        origins = np.atleast_2d(np.asarray(origins, dtype=float))
        directions = np.atleast_2d(np.asarray(directions, dtype=float))
        directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
        locations, rays, faces = self._mesh.ray.intersects_location(origins, directions, multiple_hits=True)
        best: dict[int, tuple[float, int, np.ndarray]] = {}
        for loc, ray, face in zip(locations, rays, faces, strict=True):
            d = float(np.dot(loc - origins[ray], directions[ray]))
            if d > 1e-9 and (ray not in best or d < best[ray][0]):
                best[ray] = (d, face, loc)
        out: list[SurfaceHit | None] = []
        for r in range(len(origins)):
            if r not in best:
                out.append(None)
                continue
            d, face, loc = best[r]
            normal = self._mesh.face_normals[face]
            if np.dot(normal, directions[r]) > 0:  # face the ray: meshes are wound either way
                normal = -normal
            object_id = self._ids[self._owner[face]]
            out.append(SurfaceHit(object_id, tuple(float(v) for v in loc), tuple(float(v) for v in normal),
                                  classify_hit(self.scene, object_id, loc, normal), d))
        return out

    def cast_one(self, origin, direction) -> SurfaceHit | None:
        return self.cast([origin], [direction])[0]
