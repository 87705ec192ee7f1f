"""Rotational symmetry of a model about its up axis: the smallest turn after which it looks the same.

A round vase looks the same at any heading, a square table after 90°, a rectangular coffee table after 180°, a
chair only after 360°. Used to tell whether two headings of a model are visibly different (simulated
participants do not turn a vase that already looks right). Models are in their canonical frame (metres, +Y up).
"""

from __future__ import annotations

import io

import numpy as np

#: Candidate periods, degrees; a shape matching at both 30° and 45° is taken as round (period 0).
PERIODS = (90.0, 120.0, 180.0)
TOLERANCE = 0.01  # mean distance of turned surface samples from the surface, as a fraction of the extent
SAMPLES = 600


def _turn(points: np.ndarray, degrees: float, centre: np.ndarray) -> np.ndarray:
    a = np.radians(degrees)
    c, s = np.cos(a), np.sin(a)
    x, z = points[:, 0] - centre[0], points[:, 2] - centre[2]
    return np.column_stack([c * x + s * z + centre[0], points[:, 1], -s * x + c * z + centre[2]])


def symmetry_period_deg(mesh, seed: int = 0) -> float:
    """The smallest turn about the vertical axis through the surface's centroid (every symmetry axis passes
    through it) that maps the mesh onto itself: 0 for round shapes, 90, 120 or 180 for regular ones, 360 when
    only a full turn does. Turned surface samples are measured against the surface itself, so sampling density
    does not matter."""
    import trimesh

    points, _ = trimesh.sample.sample_surface(mesh, SAMPLES, seed=seed)
    weights = mesh.area_faces / max(mesh.area, 1e-12)
    centre = (mesh.triangles_center * weights[:, None]).sum(axis=0)
    extent = float(max(np.ptp(mesh.vertices[:, 0]), np.ptp(mesh.vertices[:, 2]), 1e-6))
    query = trimesh.proximity.ProximityQuery(mesh)

    def same(degrees: float) -> bool:
        _, distances, _ = query.on_surface(_turn(np.asarray(points), degrees, centre))
        return float(np.mean(distances)) < TOLERANCE * extent

    if same(30.0) and same(45.0):
        return 0.0
    for period in PERIODS:
        if same(period):
            return period
    return 360.0


def glb_symmetry_period_deg(data: bytes, seed: int = 0) -> float:
    """:func:`symmetry_period_deg` of a GLB model (its meshes merged)."""
    import trimesh

    return symmetry_period_deg(trimesh.load(io.BytesIO(data), file_type="glb", force="mesh"), seed)


def visible_turn_deg(turn: float, period: float) -> float:
    """The part of a turn (degrees, signed) that changes how a model with this symmetry period looks."""
    if period <= 0:
        return 0.0
    if period >= 360:
        return turn
    return (turn + period / 2) % period - period / 2
