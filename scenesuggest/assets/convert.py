"""Source meshes (OBJ + MTL + textures) → GLB in the canonical frame, within a size budget.

Budget: at most :data:`FACE_BUDGET` triangles and :data:`GLB_BUDGET_BYTES` per GLB. Larger meshes are
decimated (quadric error, ``fast-simplification``) in proportion to each part's share of the faces; a
textured part that must be decimated loses its UVs and takes its texture's mean colour instead, and
textures are downsized to :data:`TEXTURE_MAX_PX`. Materials are exported double-sided, because
3D Warehouse models often have faces wound either way — except a part that is a closed, consistently and
outward-wound volume, whose back faces the viewer may cull.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from PIL import Image
from trimesh.visual.material import PBRMaterial

from ..errors import SceneSuggestError
from ..library.index import ModelInfo
from .primitives import closed_volume

FACE_BUDGET = 40000
GLB_BUDGET_BYTES = 2 * 1024 * 1024
TEXTURE_MAX_PX = 512


def load_source(path: str | Path) -> trimesh.Scene:
    """Load an OBJ (with its MTL and textures) as a scene of one mesh per material."""
    path = Path(path)
    try:
        loaded = trimesh.load(str(path), force="scene", process=False)
    except Exception as e:  # trimesh raises many types for bad files
        raise SceneSuggestError(f"cannot load mesh: {e}", file=str(path)) from None
    if not any(len(g.faces) for g in loaded.geometry.values() if isinstance(g, trimesh.Trimesh)):
        raise SceneSuggestError("mesh has no faces", file=str(path))
    return loaded


def _material(visual) -> PBRMaterial:
    """A double-sided PBR material with the source colour (and a downsized texture if kept)."""
    material = getattr(visual, "material", None)
    color = (200, 200, 200, 255)
    image = None
    if material is not None:
        pbr = material.to_pbr() if hasattr(material, "to_pbr") else material
        color = pbr.baseColorFactor if pbr.baseColorFactor is not None else color
        image = pbr.baseColorTexture
    color = np.array(color, dtype=np.uint8)
    color[3] = 255  # the MTL files say "d 0" (transparent) for opaque surfaces: ignore dissolve
    if image is not None and max(image.size) > TEXTURE_MAX_PX:
        image = image.copy()
        image.thumbnail((TEXTURE_MAX_PX, TEXTURE_MAX_PX), Image.Resampling.LANCZOS)
    return PBRMaterial(baseColorFactor=color, baseColorTexture=image, metallicFactor=0.0,
                       roughnessFactor=0.9, doubleSided=True)


def _mean_colour(material: PBRMaterial) -> np.ndarray:
    factor = np.asarray(material.baseColorFactor, dtype=float) / 255.0
    if material.baseColorTexture is not None:
        rgb = np.asarray(material.baseColorTexture.convert("RGB"), dtype=float).reshape(-1, 3).mean(axis=0) / 255.0
        factor[:3] *= rgb
    return (np.clip(factor, 0, 1) * 255).astype(np.uint8)


def canonical_meshes(source: trimesh.Scene, info: ModelInfo, face_budget: int = FACE_BUDGET) -> trimesh.Scene:
    """The source in the canonical frame (metres, +Y up, +Z front, bbox bottom centred), decimated to
    ``face_budget`` triangles in total."""
    to_canonical = info.canonical_from_raw()
    parts = [m for m in source.dump() if isinstance(m, trimesh.Trimesh) and len(m.faces)]
    total = sum(len(m.faces) for m in parts)
    keep = min(1.0, face_budget / total)
    out = trimesh.Scene()
    for i, mesh in enumerate(parts):
        material = _material(mesh.visual)
        mesh = mesh.copy()
        mesh.apply_transform(to_canonical)
        has_uv = isinstance(mesh.visual, trimesh.visual.TextureVisuals) and mesh.visual.uv is not None
        if keep < 1.0 and len(mesh.faces) > 64:
            target = max(16, int(len(mesh.faces) * keep))
            plain = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)
            mesh = plain.simplify_quadric_decimation(face_count=target)
            has_uv = False
        if has_uv and material.baseColorTexture is not None:
            visual = trimesh.visual.TextureVisuals(uv=mesh.visual.uv, material=material)
        else:
            flat = PBRMaterial(baseColorFactor=_mean_colour(material), metallicFactor=0.0, roughnessFactor=0.9,
                               doubleSided=True)
            visual = trimesh.visual.TextureVisuals(material=flat)
        part = trimesh.Trimesh(mesh.vertices, mesh.faces, visual=visual, process=False)
        visual.material.doubleSided = not closed_volume(part)
        out.add_geometry(part, geom_name=f"part{i:03d}")
    return out


def export_glb(scene: trimesh.Scene, path: str | Path) -> int:
    """Write ``scene`` as GLB; returns the file size in bytes."""
    data = scene.export(file_type="glb")
    Path(path).write_bytes(data)
    return len(data)


def convert_model(info: ModelInfo, source_path: str | Path, glb_path: str | Path) -> trimesh.Scene:
    """OBJ → canonical GLB within the byte budget (decimating harder until it fits)."""
    source = load_source(source_path)
    budget = FACE_BUDGET
    for _ in range(6):
        scene = canonical_meshes(source, info, budget)
        if export_glb(scene, glb_path) <= GLB_BUDGET_BYTES:
            return scene
        budget //= 2
    raise SceneSuggestError(f"cannot fit the model into {GLB_BUDGET_BYTES} bytes", file=str(source_path))
