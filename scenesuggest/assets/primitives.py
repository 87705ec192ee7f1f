"""Primitive parts for procedural models, in a normalised box: x, z in [−0.5, 0.5], y in [0, 1], front +Z.

A part is a ``(mesh, rgb)`` pair; :func:`assemble` scales a list of parts to a model's size (metres) and
merges parts of one colour into one mesh with one material.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import trimesh
from trimesh.visual.material import PBRMaterial

from ..scenes import frames

Part = tuple[trimesh.Trimesh, tuple[float, float, float]]
SECTIONS = 20


def box(x0: float, y0: float, z0: float, x1: float, y1: float, z1: float, rgb) -> Part:
    lo, hi = np.array([x0, y0, z0]), np.array([x1, y1, z1])
    return trimesh.creation.box(extents=hi - lo, transform=frames.translation((lo + hi) / 2)), rgb


def cylinder(x: float, z: float, y0: float, y1: float, r: float, rgb, rz: float | None = None,
             sections: int = SECTIONS) -> Part:
    """Upright (elliptic) cylinder centred on (x, z) from height y0 to y1."""
    m = trimesh.creation.cylinder(radius=1.0, height=y1 - y0, sections=sections)
    m.apply_transform(frames.translation([x, (y0 + y1) / 2, z]) @ frames.scaling([r, 1.0, rz or r])
                      @ frames.linear(frames.rotation_between([0, 0, 1], [0, 1, 0])))
    return m, rgb


def rod(p0, p1, r: float, rgb, sections: int = 12) -> Part:
    """A round bar between two points."""
    return trimesh.creation.cylinder(radius=r, segment=[p0, p1], sections=sections), rgb


def ball(x: float, y: float, z: float, r: float, rgb, ry: float | None = None, rz: float | None = None,
         subdivisions: int = 2) -> Part:
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    m.apply_transform(frames.translation([x, y, z]) @ frames.scaling([r, ry or r, rz or r]))
    return m, rgb


def lathe(profile, rgb, x: float = 0.0, z: float = 0.0, sections: int = 24) -> Part:
    """A solid of revolution about the vertical axis through (x, z); ``profile`` lists (radius, height)
    from bottom to top (start and end on the axis to close it)."""
    m = trimesh.creation.revolve(np.asarray(profile, dtype=float), sections=sections)
    m.apply_transform(frames.translation([x, 0, z]) @ frames.linear(frames.rotation_between([0, 0, 1], [0, 1, 0])))
    return m, rgb


def ring(x: float, y: float, z: float, major: float, minor: float, rgb, axis=(0, 0, 1)) -> Part:
    """A torus of radius ``major`` and tube ``minor`` whose hole looks along ``axis``."""
    m = trimesh.creation.torus(major_radius=major, minor_radius=minor, major_sections=20, minor_sections=8)
    m.apply_transform(frames.translation([x, y, z]) @ frames.linear(frames.rotation_between([0, 0, 1], axis)))
    return m, rgb


#: A piece encloses a volume when its volume is more than this many times what the rounding of its vertices'
#: coordinates can make of nothing (a sheet folded back on itself holds no volume but that).
VOLUME_ROUNDING = 64


def turn(parts: list[Part], degrees: float) -> list[Part]:
    """Rotate parts about the vertical axis (the normalised box maps onto itself for multiples of 90°)."""
    r = frames.rotation_y(math.radians(degrees))
    out = []
    for mesh, rgb in parts:
        mesh = mesh.copy()
        mesh.apply_transform(r)
        out.append((mesh, rgb))
    return out


def closed_volume(mesh: trimesh.Trimesh) -> bool:
    """True if every connected piece of ``mesh`` (faces joined by shared edges) is watertight, consistently wound
    and faces outward — encloses more volume than the rounding of its coordinates can (VOLUME_ROUNDING), not a sheet
    folded back on itself — so a viewer may cull its back faces (only its outside is ever seen).
    Watertightness and winding hold for every piece when they hold for the whole (both are per edge, and an edge is
    in one piece); solids that touch along an edge (four faces on it) therefore count as open, drawn from both sides.
    Each piece's volume is summed from its faces, without making a mesh of it."""
    welded = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)
    if not len(welded.faces) or not (welded.is_watertight and welded.is_winding_consistent):
        return False
    piece = trimesh.graph.connected_component_labels(welded.face_adjacency, node_count=len(welded.faces))
    order = np.argsort(piece, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(piece[order]) != 0])
    tri = welded.triangles[order] - welded.bounds.mean(axis=0)  # about the mesh's centre: less to cancel
    with np.errstate(all="ignore"):  # degenerate slivers: no volume, no warning
        edges = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # as trimesh's mass properties take it
        volume = np.add.reduceat(np.einsum("ij,ij->i", tri[:, 0], edges), starts) / 6.0
        area = np.add.reduceat(np.linalg.norm(edges, axis=1), starts) / 2.0
        # what rounding the vertices' coordinates leaves of a volume: their last bit over the piece's surface
        rounding = VOLUME_ROUNDING * np.finfo(float).eps * np.abs(welded.vertices).max() * area
        return bool(np.all(np.isfinite(volume)) and np.all(volume > rounding))


def _material(rgb, double_sided: bool) -> PBRMaterial:
    color = np.array([*(np.clip(np.asarray(rgb, dtype=float), 0, 1) * 255), 255], dtype=np.uint8)
    return PBRMaterial(baseColorFactor=color, metallicFactor=0.0, roughnessFactor=0.8, doubleSided=double_sided)


def assemble(parts: list[Part], size) -> trimesh.Scene:
    """Scale normalised parts to ``size`` (metres), fit the union exactly to the bbox and merge by colour.

    A merged part that is a closed, outward-wound volume gets a single-sided material (the viewer culls its
    back faces, half the shading work); open parts (a disc, a sheet) stay double-sided."""
    size = np.asarray(size, dtype=float)
    meshes = [(m.copy(), tuple(rgb)) for m, rgb in parts]
    lo = np.min([m.bounds[0] for m, _ in meshes], axis=0)
    hi = np.max([m.bounds[1] for m, _ in meshes], axis=0)
    scale = size / np.maximum(hi - lo, 1e-9)
    fit = (frames.translation([0, 0, 0]) @ frames.scaling(scale)
           @ frames.translation([-(lo[0] + hi[0]) / 2, -lo[1], -(lo[2] + hi[2]) / 2]))
    by_colour: dict[tuple, list[trimesh.Trimesh]] = defaultdict(list)
    for m, rgb in meshes:
        m.apply_transform(fit)
        by_colour[rgb].append(m)
    scene = trimesh.Scene()
    for i, (rgb, group) in enumerate(by_colour.items()):
        merged = trimesh.util.concatenate(group)
        merged.visual = trimesh.visual.TextureVisuals(material=_material(rgb, not closed_volume(merged)))
        scene.add_geometry(merged, geom_name=f"part{i:02d}")
    return scene
