"""Asset pipeline: OBJ → canonical GLB within budget, procedural models, thumbnails, atomic library builds."""

import io
import json

import numpy as np
import pytest
import trimesh
from PIL import Image

from scenesuggest.assets.build import build_library, file_stem
from scenesuggest.assets.convert import GLB_BUDGET_BYTES, convert_model
from scenesuggest.assets.primitives import closed_volume
from scenesuggest.assets.procedural import BUILDERS, procedural_model
from scenesuggest.assets.render import render_thumbnail
from scenesuggest.corpora.corpus import Corpus
from scenesuggest.errors import SceneSuggestError

DESK = "569e2fce2f1ab3be617e9d9aa36a8137"  # 1.3k faces, no texture
FRUIT_BOWL = "9bc687dcffc25b955d20b6ca8788556a"  # 36k faces, textured: must be decimated
ROOM = "room01"


def coverage(png: bytes) -> float:
    alpha = np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))[..., 3]
    return float((alpha > 0).mean())


@pytest.mark.parametrize("model_id", [DESK, FRUIT_BOWL, ROOM])
def test_glb_loads_back_in_the_canonical_frame(stanford, tmp_path, model_id):
    info = stanford.models[model_id]
    convert_model(info, info.mesh, tmp_path / "m.glb")
    assert (tmp_path / "m.glb").stat().st_size <= GLB_BUDGET_BYTES
    back = trimesh.load(tmp_path / "m.glb", force="scene")
    lo, hi = back.bounds
    assert hi - lo == pytest.approx(info.size, rel=1e-3, abs=1e-3)
    assert lo[1] == pytest.approx(0, abs=1e-4)  # bottom at the origin
    assert (lo + hi)[[0, 2]] / 2 == pytest.approx([0, 0], abs=1e-3)


def test_desk_front_faces_plus_z(stanford, tmp_path):
    """The desk's drawers and handles are on its front: far more detail near +Z than near −Z."""
    info = stanford.models[DESK]
    scene = convert_model(info, info.mesh, tmp_path / "d.glb")
    z = np.concatenate([g.vertices for g in scene.dump()])[:, 2]
    depth = info.size[2]
    assert info.size[0] > depth  # wide and shallow: X runs across, Z is depth
    assert (z > 0.2 * depth).sum() > 2 * (z < -0.2 * depth).sum()


def test_thumbnails_show_the_object(stanford, tmp_path):
    info = stanford.models[DESK]
    png = render_thumbnail(convert_model(info, info.mesh, tmp_path / "d.glb"), 128)
    image = Image.open(io.BytesIO(png))
    assert image.size == (128, 128) and image.mode == "RGBA"
    assert 0.2 < coverage(png) < 0.9
    pixels = np.asarray(image)[..., :3][np.asarray(image)[..., 3] > 0]
    assert pixels.std() > 10  # shaded, not a flat silhouette


@pytest.mark.parametrize("object_type", sorted(BUILDERS))
def test_procedural_model_fits_its_box(object_type):
    size = (0.6, 0.9, 0.4) if object_type != "Room" else (1.0, 1.0, 1.0)
    scene = procedural_model(object_type, size)
    lo, hi = scene.bounds
    assert hi - lo == pytest.approx(size, abs=1e-6)
    assert lo[1] == pytest.approx(0, abs=1e-9)
    assert all(isinstance(g.visual.material.baseColorFactor, np.ndarray) for g in scene.geometry.values())


def test_closed_volume_tells_solids_from_sheets_and_inside_out_shells():
    assert closed_volume(trimesh.creation.box())
    assert closed_volume(trimesh.util.concatenate([trimesh.creation.box(), trimesh.creation.icosphere()]))
    box = trimesh.creation.box()
    assert not closed_volume(trimesh.Trimesh(box.vertices, box.faces[2:]))  # one side missing: open
    inside_out = trimesh.creation.icosphere()
    inside_out.invert()
    assert not closed_volume(trimesh.util.concatenate([trimesh.creation.box(extents=[4, 4, 4]), inside_out]))
    assert not closed_volume(trimesh.Trimesh(np.eye(3), [[0, 1, 2]]))
    far = np.array([[0.0, 0.0, 0.0], [1e-5, 0.0, 0.0], [0.0, 0.0, 1e-5]]) + [3.0, 2.0, -4.0]
    for back in ([0, 2, 1], [1, 0, 2], [2, 1, 0]):  # a sheet folded back on itself: watertight, no volume
        folded = trimesh.Trimesh(far, [[0, 1, 2], back], process=False)
        assert folded.is_watertight and not closed_volume(folded), back
    rng = np.random.default_rng(0)
    for _ in range(200):  # small sheets far away: what rounding leaves of their volume is no volume
        corner = rng.uniform(-100.0, 100.0, 3)
        sheet = corner + rng.uniform(-1e-5, 1e-5, (3, 3))
        assert not closed_volume(trimesh.Trimesh(sheet, [[0, 1, 2], [1, 0, 2]], process=False))
    ball = trimesh.creation.icosphere(radius=1e-4)
    ball.apply_translation([50.0, 0.0, 0.0])
    assert closed_volume(ball)
    screw = trimesh.creation.box(extents=[1e-3, 1e-3, 1e-3])  # a millimetre cube far from the origin is a solid
    screw.apply_translation([40.0, 3.0, -25.0])
    assert closed_volume(trimesh.util.concatenate([screw, trimesh.creation.box(extents=[2, 2, 2])]))
    inside_out_screw = screw.copy()
    inside_out_screw.invert()
    assert not closed_volume(trimesh.util.concatenate([inside_out_screw, trimesh.creation.box(extents=[2, 2, 2])]))


def test_only_closed_parts_are_single_sided():
    """A chair is all solids (back faces may be culled); a CD is a flat disc, seen from both sides."""
    chair = procedural_model("Chair", (0.5, 0.9, 0.5))
    assert all(not g.visual.material.doubleSided for g in chair.geometry.values())
    disc = procedural_model("CD", (0.12, 0.002, 0.12))
    assert any(g.visual.material.doubleSided for g in disc.geometry.values())


def test_converted_parts_are_double_sided_unless_closed(stanford, tmp_path):
    info = stanford.models[DESK]
    scene = convert_model(info, info.mesh, tmp_path / "d.glb")
    for g in scene.geometry.values():
        assert g.visual.material.doubleSided == (not closed_volume(g))


def test_procedural_models_are_composed_of_recognisable_parts(ai2thor):
    def components(object_type):
        scene = procedural_model(object_type, ai2thor.models[f"ai2thor:{object_type}"].size)
        return sum(len(g.split(only_watertight=False)) for g in scene.geometry.values())

    assert components("Chair") >= 8  # four legs, seat, two back posts, back rest
    assert components("DeskLamp") >= 3  # base, stem, shade
    assert components("DiningTable") >= 5  # top and four legs
    assert components("Bed") >= 6


def test_every_ai2thor_type_has_a_builder(ai2thor):
    types = {m.category for m in ai2thor.models.values()}
    assert types <= set(BUILDERS)


def test_build_library_for_the_demo_corpus(ai2thor, tmp_path):
    ids = ["ai2thor:Chair", "ai2thor:Mug", "ai2thor:Room"]
    report = build_library(ai2thor, tmp_path / "lib", model_ids=ids, thumbnail_px=64)
    assert report["built"] == 3 and report["max_glb_bytes"] < 200_000
    index = json.loads((tmp_path / "lib" / "library.json").read_text())
    entries = {m["id"]: m for m in index["models"]}
    assert len(entries) == len(ai2thor.models)
    assert entries["ai2thor:Mug"]["asset"] == f"models/{file_stem('ai2thor:Mug')}.glb"
    assert entries["ai2thor:Sofa"]["asset"] is None  # not asked for
    mug = trimesh.load(tmp_path / "lib" / entries["ai2thor:Mug"]["asset"], force="scene")
    assert np.ptp(mug.bounds, axis=0) == pytest.approx(entries["ai2thor:Mug"]["size"], abs=1e-6)
    assert coverage((tmp_path / "lib" / entries["ai2thor:Chair"]["thumbnail"]).read_bytes()) > 0.1
    assert (tmp_path / "lib" / "taxonomy.json").is_file()


def test_a_failed_build_leaves_nothing_behind(ai2thor, tmp_path):
    bad = dict(ai2thor.models)
    broken = tmp_path / "broken.obj"
    broken.write_text("v 0 0 0\nf 1 2 3\n")
    mug = bad["ai2thor:Mug"]
    bad["broken"] = type(mug)(id="broken", category="Mug", category_path=["Mug"], mesh=str(broken),
                              size_source="mesh", raw_bbox=((0, 0, 0), (1, 1, 1)))
    corpus = Corpus("test", [], bad, ai2thor.taxonomy)
    with pytest.raises(SceneSuggestError):
        build_library(corpus, tmp_path / "lib", model_ids=["ai2thor:Mug", "broken"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.obj"]


def test_unknown_model_ids_are_refused(ai2thor, tmp_path):
    with pytest.raises(SceneSuggestError, match="unknown model ids: nope"):
        build_library(ai2thor, tmp_path / "lib", model_ids=["nope"])


def test_what_is_written_whole_gets_the_usual_permissions(ai2thor, tmp_path):
    """A library folder and the files written atomically get the modes ``mkdir`` and ``open`` would give (the
    umask applied), not the private modes of their temporary names; a replaced file keeps its mode; a link is
    written through."""
    import os
    import stat

    from scenesuggest.atomic import write_atomically

    old = os.umask(0o027)
    try:
        build_library(ai2thor, tmp_path / "lib", model_ids=["ai2thor:Mug"], thumbnail_px=32)
        fresh = write_atomically(tmp_path / "fresh.bin", b"x")
        kept = tmp_path / "kept.bin"
        kept.write_bytes(b"old")
        kept.chmod(0o600)
        write_atomically(kept, b"new")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "lib").stat().st_mode) == 0o750
    assert stat.S_IMODE((tmp_path / "lib" / "library.json").stat().st_mode) == 0o640
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o640
    assert stat.S_IMODE(kept.stat().st_mode) == 0o600 and kept.read_bytes() == b"new"
    link = tmp_path / "link.bin"
    link.symlink_to(kept)
    write_atomically(link, b"through the link")
    assert link.is_symlink() and kept.read_bytes() == b"through the link"


def test_a_library_is_rebuilt_when_the_code_that_sizes_its_models_changes():
    """A model's box in a library is what its corpus loader measured (an AI2-THOR type's median box): the library's
    code digest covers the loaders as well as the asset builders, so `study prepare` rebuilds a library whose
    models a changed loader would size otherwise."""
    from scenesuggest.assets.build import BUILDERS
    from scenesuggest.digest import PACKAGE

    covered = {p for pattern in BUILDERS for p in PACKAGE.glob(pattern)}
    assert {PACKAGE / "corpora" / "ai2thor.py", PACKAGE / "corpora" / "stanford.py",
            PACKAGE / "assets" / "procedural.py"} <= covered
