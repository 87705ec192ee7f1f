"""Rotational symmetry of a model about its up axis: the smallest turn after which it looks the same.

A round vase looks the same at any heading, a square table after 90°, a rectangular coffee table after 180°, a
chair only after 360°. Used to tell whether two headings of a model are visibly different: simulated
participants do not turn a vase that already looks right, and orientation error is folded by the period
(:mod:`scenesuggest.contract.pose_error`). Models are in their canonical frame (metres, +Y up).

:func:`corpus_periods` finds the period of every model of a corpus that has a mesh (its OBJ source, its built
GLB, or the procedural model of its type). A model without a mesh takes the strictest (largest) period measured
on the meshes of its category, and none (360°, nothing folded) when its category has no mesh;
:meth:`ModelPeriods.of` also refuses a period that an instance's footprint rules out (a footprint that is not
square cannot be round or square). Periods measured from files are cached by file content in the user's cache
folder (``$SCENESUGGEST_CACHE``, else ``$XDG_CACHE_HOME/scenesuggest``, else ``~/.cache/scenesuggest``).
"""

from __future__ import annotations

import hashlib
import io
import json
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import write_atomically
from ..scenes.scene import ROOM

#: Candidate periods, degrees; a shape matching at both 30° and 45° is taken as round (period 0).
PERIODS = (90.0, 120.0, 180.0)
TOLERANCE = 0.01  # mean distance of turned surface samples from the surface, as a fraction of the extent
SAMPLES = 600
NONE = 360.0
#: A footprint whose sides differ by this factor or more is neither round nor square.
SQUARE_ASPECT = 1.1
#: Bumped whenever :func:`symmetry_period_deg` changes what it answers, so cached periods are recomputed.
ALGORITHM = 1
CACHE_ENV = "SCENESUGGEST_CACHE"


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
    return NONE


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


@dataclass(frozen=True)
class ModelPeriods:
    """Symmetry periods (degrees about the up axis) of a corpus's models.

    ``measured``: model id → period measured on the model's own mesh; ``by_category``: category → the
    strictest (largest) period measured on the meshes of its models.
    """

    measured: dict[str, float] = field(default_factory=dict)
    by_category: dict[str, float] = field(default_factory=dict)

    def of(self, model_id: str, category: str, footprint: tuple[float, float] | None = None) -> tuple[float, str]:
        """(period, source) of one instance: source ``mesh``, ``category`` or ``none`` (360°, not folded).
        ``footprint`` (x, z extent in metres) rules out round and square periods for oblong instances."""
        if model_id in self.measured:
            period, source = self.measured[model_id], "mesh"
        elif category in self.by_category:
            period, source = self.by_category[category], "category"
        else:
            return NONE, "none"
        if footprint is not None and period in (0.0, 90.0):
            a, b = sorted(float(v) for v in footprint)
            if b >= SQUARE_ASPECT * max(a, 1e-9):
                period = 180.0
        return period, source


def cache_dir() -> Path:
    """The folder of the symmetry cache (see the module docstring)."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "scenesuggest"


class _Cache:
    """Periods by key, read once and written back (atomically) when something was added."""

    def __init__(self, folder: Path | None):
        self.path = folder / f"symmetry-v{ALGORITHM}.json" if folder else None
        self.values: dict[str, float] = {}
        self.dirty = False
        if self.path is not None and self.path.is_file():
            try:
                self.values = {k: float(v) for k, v in json.loads(self.path.read_text()).items()}
            except (OSError, ValueError, TypeError, AttributeError):
                self.values = {}

    def get(self, key: str, compute: Callable[[], float]) -> float:
        if key not in self.values:
            self.values[key] = float(compute())
            self.dirty = True
        return self.values[key]

    def save(self) -> None:
        if not (self.dirty and self.path is not None):
            return
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            write_atomically(self.path, json.dumps(self.values, sort_keys=True).encode())
        except OSError:
            pass  # a cache that cannot be written only costs time


def _file_key(path: Path, transform: np.ndarray) -> str:
    digest = hashlib.sha256(path.read_bytes())
    digest.update(np.round(np.asarray(transform, dtype=float), 9).tobytes())
    return digest.hexdigest()


def _period_of_model(model, cache: _Cache, base: Path | None = None) -> float | None:
    """The period of one model's mesh: its OBJ source in the canonical frame, its built GLB (``asset``, relative
    to ``base`` when not absolute), or the procedural model of its type; None when it has none."""
    import trimesh

    if model.mesh and Path(model.mesh).is_file():
        path, transform = Path(model.mesh), model.canonical_from_raw()

        def compute() -> float:
            mesh = trimesh.load(path, force="mesh", skip_materials=True)
            return symmetry_period_deg(mesh.apply_transform(transform))

        return cache.get(_file_key(path, transform), compute)
    asset = Path(model.asset) if model.asset else None
    if asset is not None and not asset.is_absolute() and base is not None:
        asset = base / asset
    if asset is not None and asset.is_file():
        path = asset
        return cache.get(_file_key(path, np.eye(4)), lambda: glb_symmetry_period_deg(path.read_bytes()))
    if model.size_source == "procedural":
        from .procedural import procedural_model

        size = tuple(round(float(v), 4) for v in model.size)
        key = f"procedural:{model.category}:{size}"
        return cache.get(key, lambda: symmetry_period_deg(procedural_model(model.category, size).to_mesh()))
    return None


def corpus_periods(models: Iterable, progress: Callable[[Iterable, str], Iterable] | None = None,
                   cache: Path | None | bool = True, base: str | Path | None = None) -> ModelPeriods:
    """:class:`ModelPeriods` of ``models`` (:class:`~scenesuggest.library.index.ModelInfo`); ``cache``: True for the
    user's cache folder, a folder, or None/False for no cache; ``base``: the folder of a model library, whose
    assets are named relative to it."""
    progress = progress or (lambda items, label="": items)
    models = list(models)
    store = _Cache(cache_dir() if cache is True else (Path(cache) if cache else None))
    measured: dict[str, float] = {}
    try:
        for model in progress([m for m in models if m.category != ROOM], "symmetry"):
            period = _period_of_model(model, store, Path(base) if base else None)
            if period is not None:
                measured[model.id] = period
    finally:
        store.save()
    by_category: dict[str, float] = {}
    for model in models:
        if model.id in measured:
            by_category[model.category] = max(by_category.get(model.category, 0.0), measured[model.id])
    return ModelPeriods(measured, by_category)
