"""Rotational symmetry about the up axis, from surface samples and from built GLB models."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from scenesuggest.assets.symmetry import glb_symmetry_period_deg, symmetry_period_deg, visible_turn_deg


@pytest.mark.parametrize("mesh,period", [
    (trimesh.creation.cylinder(radius=0.2, height=0.5, sections=64), 0.0),
    (trimesh.creation.box((0.6, 0.6, 0.4)), 90.0),  # 0.6 × 0.6 footprint once +Y is up
    (trimesh.creation.box((1.2, 0.45, 0.6)), 180.0),
    (trimesh.creation.cylinder(radius=0.3, height=0.2, sections=3), 120.0),
    (trimesh.util.concatenate([trimesh.creation.box((1.0, 0.4, 0.5)),
                               trimesh.creation.box((0.3, 0.8, 0.5)).apply_translation((0.35, 0.4, 0.0))]), 360.0),
])
def test_periods_of_simple_shapes(mesh, period):
    # canonical frame: +Y up (trimesh builds along +Z)
    mesh = mesh.copy().apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0)))
    assert symmetry_period_deg(mesh) == period


def test_glb_models_and_visible_turns():
    chair_like = trimesh.util.concatenate([trimesh.creation.box((0.5, 0.05, 0.5)),
                                           trimesh.creation.box((0.5, 0.6, 0.05)).apply_translation((0, 0.3, -0.22))])
    table = trimesh.creation.box((1.2, 0.05, 0.6))
    assert glb_symmetry_period_deg(trimesh.Scene(chair_like).export(file_type="glb")) == 360.0
    assert glb_symmetry_period_deg(trimesh.Scene(table).export(file_type="glb")) == 180.0
    assert visible_turn_deg(170.0, 180.0) == pytest.approx(-10.0)
    assert visible_turn_deg(100.0, 90.0) == pytest.approx(10.0)
    assert visible_turn_deg(123.0, 0.0) == 0.0 and visible_turn_deg(-150.0, 360.0) == -150.0


def test_periods_of_a_corpus_are_cached_and_meshless_models_take_their_category_period(tmp_path, monkeypatch):
    from scenesuggest.assets import symmetry
    from scenesuggest.library.index import ModelInfo

    glb = tmp_path / "table.glb"
    glb.write_bytes(trimesh.Scene(trimesh.creation.box((1.2, 0.05, 0.6))).export(file_type="glb"))
    models = [ModelInfo("t1", "Table", ["Table"], asset=str(glb)), ModelInfo("t2", "Table", ["Table"]),
              ModelInfo("v1", "Vase", ["Vase"])]
    periods = symmetry.corpus_periods(models, cache=tmp_path / "cache")
    assert periods.of("t1", "Table") == (180.0, "mesh")
    assert periods.of("t2", "Table") == (180.0, "category") and periods.of("v1", "Vase") == (360.0, "none")
    calls = []
    monkeypatch.setattr(symmetry, "symmetry_period_deg", lambda *a, **k: calls.append(1) or 0.0)
    again = symmetry.corpus_periods(models, cache=tmp_path / "cache")
    assert again.measured == periods.measured and not calls  # read from the cache, not measured again
    # a round category's period cannot hold for an oblong instance
    round_ = symmetry.ModelPeriods({}, {"Bowl": 0.0})
    assert round_.of("b", "Bowl", (0.3, 0.3)) == (0.0, "category")
    assert round_.of("b", "Bowl", (0.6, 0.3)) == (180.0, "category")
