"""``stanford:DIR`` — the Stanford Scene Database (Fisher et al. 2012) in the world frame.

Expected layout (the shared data layout; the original database puts ``models/`` inside ``DIR``)::

    DIR/scenes/sceneNNNNN.txt                 the scenes (inches, +Z up)
    DIR/fields/names.txt, tags.txt            3D Warehouse names and tags (optional)
    DIR/shapenetsem_meta/StanfordModelDB_MetaInfo[_corrected_v0].csv   ShapeNetSem metadata (optional)
    DIR/categories/coca_models_pruned_categories.txt                   coarse labels (optional)
    meshes: DIR/models/, else ../stanford_models/models/, else $SCENESUGGEST_STANFORD_MESHES (optional)

Each model's bbox comes from its OBJ mesh when present; otherwise from the metadata's aligned dimensions,
placed so that the scene contacts lie on the face that touches the parent (the database puts the
contact at the centre of that face); without either, a 20 cm box grown to reach what rests on it.
Categories come from the ShapeNetSem labels, then the first WordNet lemma, then the coarse labels.
A scene's walls are measured on its room model's mesh (:func:`scenesuggest.scenes.walls.mesh_walls`) when the mesh is
there; otherwise the room's box stands for them.
"""

from __future__ import annotations

import os
from collections import defaultdict
from pathlib import Path

import numpy as np

from ..errors import SceneSuggestError
from ..library.index import ModelInfo
from ..library.objfile import obj_bounds
from ..scenes import frames, surfaces
from ..scenes.scene import ROOM, UNKNOWN, ObjectInstance, Scene
from ..scenes.scene_types import infer_scene_type
from ..scenes.taxonomy import Taxonomy
from ..scenes.walls import mesh_walls
from .corpus import Corpus, Progress, no_progress
from .shapenetsem import (
    DEFAULT_FRONT,
    DEFAULT_UNIT,
    DEFAULT_UP,
    ModelMeta,
    camel,
    category_paths,
    read_field_file,
    read_metadata,
)
from .stanford_format import RawObject, read_scene_file

#: Stanford world (inches, +Z up) → our world (metres, +Y up).
WORLD = frames.scaling(frames.INCH) @ frames.linear(frames.Z_UP_TO_Y_UP)
#: Size of a model we know nothing about (no mesh, no metadata), in metres.
GUESS_SIZE_M = 0.2
MESHES_ENV = "SCENESUGGEST_STANFORD_MESHES"


def find_mesh_dir(root: Path, meshes: str | Path | None = None) -> Path | None:
    candidates = [meshes, os.environ.get(MESHES_ENV), root / "models", root.parent / "stanford_models" / "models"]
    for c in candidates:
        if c and Path(c).is_dir():
            return Path(c)
    return None


def _metadata_file(root: Path) -> Path | None:
    for name in ("StanfordModelDB_MetaInfo_corrected_v0.csv", "StanfordModelDB_MetaInfo.csv"):
        for d in (root / "shapenetsem_meta", root):
            if (d / name).is_file():
                return d / name
    return None


def load_stanford(directory: str | Path, meshes: str | Path | None = None,
                  progress: Progress = no_progress) -> Corpus:
    """Load every scene of a Stanford Scene Database folder; all or nothing (errors name file and line)."""
    root = Path(directory)
    scene_files = sorted((root / "scenes").glob("*.txt")) if (root / "scenes").is_dir() else []
    if not scene_files:
        raise SceneSuggestError("no scenes found (expected scenes/*.txt)", file=str(root))
    raw_scenes = {p.stem: read_scene_file(p) for p in progress(scene_files, "reading scenes")}

    meta_file = _metadata_file(root)
    meta = read_metadata(meta_file) if meta_file else {}
    names = read_field_file(root / "fields" / "names.txt") if (root / "fields" / "names.txt").is_file() else {}
    tags = read_field_file(root / "fields" / "tags.txt") if (root / "fields" / "tags.txt").is_file() else {}
    coarse_file = root / "categories" / "coca_models_pruned_categories.txt"
    coarse = read_field_file(coarse_file) if coarse_file.is_file() else {}

    paths = category_paths(meta)
    used = {o.model_id for objs in raw_scenes.values() for o in objs}
    for model_id in sorted(used | set(names)):
        if model_id.startswith("room"):
            paths[model_id] = [ROOM]
        elif model_id not in paths:
            paths[model_id] = [camel(coarse[model_id][0])] if coarse.get(model_id) else [UNKNOWN]
    taxonomy = Taxonomy.from_paths(paths.values())

    mesh_dir = find_mesh_dir(root, meshes)
    models = _model_infos(sorted(used | set(names)), raw_scenes, meta, names, tags, paths, mesh_dir)
    placements = {m.id: (np.linalg.inv(m.canonical_from_raw()), m.size) for m in models.values()}
    scenes = [_convert_scene(sid, objs, models, placements, taxonomy, root / "scenes" / f"{sid}.txt")
              for sid, objs in progress(raw_scenes.items(), "converting scenes")]
    walls: dict[tuple, list | None] = {}
    for scene in scenes:
        rooms = [o for o in scene.roots() if o.category == ROOM]
        if rooms and models[rooms[0].model_id].mesh:
            room = rooms[0]
            key = (room.model_id, room.transform.round(6).tobytes())
            if key not in walls:
                walls[key] = _room_walls(models[room.model_id], room.transform)
            scene.walls = walls[key]
    return Corpus(f"stanford:{root}", scenes, models, taxonomy)


def _room_walls(model: ModelInfo, transform: np.ndarray) -> list | None:
    """The walls of a room model's mesh placed by ``transform`` (canonical → world); None when the mesh has none
    (the room's box then stands for them). A mesh that cannot be read is an error naming the file."""
    import trimesh

    try:
        mesh = trimesh.load(model.mesh, force="mesh", skip_materials=True, process=False)
        vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    except Exception as e:  # trimesh raises many kinds on malformed files
        raise SceneSuggestError(f"cannot read the room mesh: {e}", file=str(model.mesh)) from None
    return mesh_walls(frames.apply(transform @ model.canonical_from_raw(), vertices), faces) or None


def _model_infos(model_ids, raw_scenes, meta, names, tags, paths, mesh_dir) -> dict[str, ModelInfo]:
    contacts = defaultdict(list)  # model id -> [(local contact point, local outward face normal)]
    carried = defaultdict(list)  # model id -> contact points of its children, in its raw frame
    for objs in raw_scenes.values():
        for o in objs:
            c = o.contact
            if c is not None:
                contacts[o.model_id].append(_local_contact(o, *c))
                parent = objs[o.parent_index]
                carried[parent.model_id].append(frames.apply(np.linalg.inv(parent.transform), c[0][None])[0])
    models = {}
    for model_id in model_ids:
        m = meta.get(model_id)
        up = (m.up if m and m.up else DEFAULT_UP)
        front = (m.front if m and m.front else DEFAULT_FRONT)
        unit = m.unit if m and m.unit else DEFAULT_UNIT
        mesh = mesh_dir / f"{model_id}.obj" if mesh_dir else None
        if mesh is not None and mesh.is_file():
            lo, hi = obj_bounds(mesh)
            source = "mesh"
        else:
            mesh = None
            lo, hi, source = _bbox_from_contacts(up, front, unit, m, contacts.get(model_id, []))
            if source == "guess" and carried.get(model_id):  # at least reach what rests on it
                lo = np.minimum(lo, np.min(carried[model_id], axis=0))
                hi = np.maximum(hi, np.max(carried[model_id], axis=0))
        path = paths[model_id]
        models[model_id] = ModelInfo(
            id=model_id, category=path[-1], category_path=list(path),
            name=" ".join((names.get(model_id) or [m.name if m else ""])[0].split()),
            tags=tags.get(model_id, m.tags if m else []),
            description=", ".join(m.wnlemmas) if m else "",
            up=tuple(float(v) for v in up), front=tuple(float(v) for v in front), unit=float(unit),
            raw_bbox=(tuple(float(v) for v in lo), tuple(float(v) for v in hi)),
            size_source=source, mesh=str(mesh) if mesh else None,
        )
    return models


def _local_contact(o: RawObject, point: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The contact point in the child's raw model frame and the outward normal of its touching face."""
    p = frames.apply(np.linalg.inv(o.transform), point[None])[0]
    n = frames.direction_in_frame(o.transform, -normal[None])[0]
    return p, n


def _bbox_from_contacts(up, front, unit, m: ModelMeta | None, contacts):
    """Raw-frame bbox of a model without a mesh: metadata size, centred on its contacts."""
    r = frames.alignment(up, front)
    if m is not None and m.dims_cm is not None and min(m.dims_cm) > 0:
        size = np.asarray(m.dims_cm) / 100.0
        source = "metadata"
    else:
        size = np.full(3, GUESS_SIZE_M)
        source = "guess"
    centres = []
    for p, n in contacts:
        q = r @ p * unit  # aligned frame, metres
        face = frames.face_of_direction(r @ n)
        axis_normal = np.asarray(frames.FACE_NORMALS[face])
        centres.append(q - axis_normal * size / 2)
    centre = np.median(centres, axis=0) if centres else np.array([0.0, size[1] / 2, 0.0])
    corners = frames.box_corners(size) + centre - np.array([0.0, size[1] / 2, 0.0])
    raw = corners @ r / unit  # back to the raw frame (r is orthonormal)
    return raw.min(axis=0), raw.max(axis=0), source


def _convert_scene(scene_id: str, objs: list[RawObject], models: dict[str, ModelInfo],
                   placements: dict[str, tuple[np.ndarray, tuple]], taxonomy: Taxonomy, file: Path) -> Scene:
    """One scene in the world frame; ``placements`` holds each model's (raw ← canonical map, size)."""
    transforms = [WORLD @ o.transform @ placements[o.model_id][0] for o in objs]
    scene = Scene(scene_id, ROOM, source=f"stanford:{scene_id}")
    for o, transform in zip(objs, transforms, strict=True):
        size = placements[o.model_id][1]
        inst = ObjectInstance(id=str(o.index), model_id=o.model_id, category=models[o.model_id].category,
                              transform=transform, size=size)
        c = o.contact
        if o.parent_index >= 0:
            inst.parent = str(o.parent_index)
        if c is not None:
            point = frames.apply(WORLD, c[0][None])[0]
            normal = frames.Z_UP_TO_Y_UP @ c[1]
            parent = objs[o.parent_index]
            inst.contact_point = tuple(float(v) for v in point)
            inst.contact_normal = tuple(float(v) for v in normal)
            inst.surface_type = surfaces.surface_type(transforms[o.parent_index],
                                                      placements[parent.model_id][1], point, normal)
            inst.attachment_face = surfaces.attachment_face(transform, normal)
        scene.objects[inst.id] = inst
    scene.validate(file=str(file), lines={str(o.index): o.line for o in objs})
    scene.scene_type = infer_scene_type((o.category for o in scene), taxonomy)
    scene.type_from_objects = True
    return scene
