"""Context queries on a synthetic corpus with known answers; bad input; the beyond-the-paper options."""

import math
from dataclasses import replace

import numpy as np
import pytest

from scenesuggest.errors import SceneSuggestError
from scenesuggest.learning.priors import Priors
from scenesuggest.scenes import frames, poses
from scenesuggest.suggestion.suggest import ContextQuery, Engine, EngineOptions


@pytest.fixture(scope="module")
def engine(corpus):
    return Engine(Priors.fit(corpus.scenes, corpus.taxonomy))


@pytest.fixture
def study(corpus):
    return corpus.scenes[0]


def desk_of(scene):
    return next(o for o in scene if o.category == "Desk")


def on_desk(scene, dx=0.0, dz=0.0):
    desk = desk_of(scene)
    return desk, frames.apply(desk.transform, [[dx, 0.75, dz]])[0]


def ranked(results):
    return [s.category for s in results]


def test_a_desk_top_suggests_what_desks_carry(engine, study):
    desk = desk_of(study)
    empty = study
    for child in study.children(desk.id):
        empty = empty.without(child.id)
    _, point = on_desk(empty, 0.0, -0.2)
    results = engine.suggest(ContextQuery(empty, desk.id, point, (0, 1, 0)), "full")
    assert ranked(results)[0] == "Monitor"  # where monitors stand
    assert set(ranked(results)[:3]) == {"Monitor", "Keyboard", "Speaker"}
    top = results[0]
    assert top.rank == 1 and top.models == ("m:Monitor",) and top.attachment_face == "bottom"
    assert top.terms["occurrence"] == pytest.approx(1.0) and top.terms["surface"] == pytest.approx(1.0)
    assert np.allclose(top.placement[:3, 3], point)  # bottom centre on the click
    assert [s.score for s in results] == sorted((s.score for s in results), reverse=True)


def test_counts_already_on_the_parent_lower_the_occurrence(engine, study):
    desk, point = on_desk(study, 0.0, 0.0)
    full = {s.category: s for s in engine.suggest(ContextQuery(study, desk.id, point, (0, 1, 0)))}
    assert full["Monitor"].terms["occurrence"] == 0.0  # one monitor per desk, and there is one
    assert full["Speaker"].terms["occurrence"] == 0.0  # two speakers per desk, and there are two
    one_speaker = study.without(next(o.id for o in study.children(desk.id) if o.category == "Speaker"))
    again = {s.category: s for s in engine.suggest(ContextQuery(one_speaker, desk.id, point, (0, 1, 0)))}
    assert again["Speaker"].terms["occurrence"] == pytest.approx(1.0)


def test_basic_keeps_the_canonical_pose_and_full_turns_the_chair_to_the_desk(engine, study):
    desk = desk_of(study)
    scene = study.without(next(o.id for o in study if o.category == "OfficeChair"))
    point = frames.apply(desk.transform, [[0.0, 0.0, 0.7]])[0]
    point[1] = 0.0
    query = ContextQuery(scene, "room", point, (0, 1, 0))
    full = next(s for s in engine.suggest(query, "full") if s.category == "OfficeChair")
    basic = next(s for s in engine.suggest(query, "basic") if s.category == "OfficeChair")
    assert full.heading_deg == pytest.approx(180.0, abs=10)  # facing the desk, whose front is +Z
    assert basic.heading_deg == pytest.approx(0.0)
    assert np.allclose(basic.placement[:3, :3], np.eye(3))
    assert ranked(engine.suggest(query, "full")) == ranked(engine.suggest(query, "basic"))


def test_wall_objects_follow_height(engine, study):
    low = engine.suggest(ContextQuery(study, "room", (0.5, 0.3, -2.0), (0, 0, 1)))
    high = engine.suggest(ContextQuery(study, "room", (0.5, 1.8, -2.0), (0, 0, 1)))
    assert ranked(low)[0] == "PowerSocket" and ranked(high)[0] == "Poster"
    poster = high[0]
    assert poster.attachment_face == "back"
    assert np.allclose(poster.placement[:3, 2], [0, 0, 1])  # facing out of the wall
    assert np.allclose(poster.placement[:3, 1], [0, 1, 0])  # upright


def test_surface_and_scene_types_are_derived(engine, study):
    desk, point = on_desk(study)
    prep = engine.prepare(ContextQuery(study, desk.id, point, (0, 2, 0)))
    assert prep.surface_type == "up_exterior" and prep.scene_type == "Study"
    assert np.allclose(prep.normal, [0, 1, 0])
    assert [r.id for r, rel in prep.references if rel == "parent"] == [desk.id]
    renamed = replace(study, scene_type="Room")
    inferred = engine.with_options(infer_scene_type=True).prepare(ContextQuery(renamed, desk.id, point, (0, 1, 0)))
    assert inferred.scene_type == "Study"
    overridden = engine.prepare(ContextQuery(renamed, desk.id, point, (0, 1, 0), scene_type="Bedroom"))
    assert overridden.scene_type == "Bedroom"


@pytest.mark.parametrize(("change", "field"), [
    ({"parent_id": "nope"}, "parent"),
    ({"normal": (0, 0, 0)}, "normal"),
    ({"normal": (0, math.nan, 1)}, "normal"),
    ({"point": (0, math.inf, 0)}, "point"),
    ({"point": (1, 2)}, "point"),
    ({"point": "here"}, "point"),
    ({"point": (40.0, 0.75, 0.0)}, "point"),
])
def test_bad_queries_name_the_field(engine, study, change, field):
    desk, point = on_desk(study)
    query = replace(ContextQuery(study, desk.id, tuple(point), (0, 1, 0)), **change)
    with pytest.raises(SceneSuggestError) as info:
        engine.suggest(query)
    assert info.value.field == field


def test_bad_mode_top_and_options(engine, study):
    desk, point = on_desk(study)
    query = ContextQuery(study, desk.id, point, (0, 1, 0))
    with pytest.raises(SceneSuggestError, match="none"):
        engine.suggest(query, "none")
    with pytest.raises(SceneSuggestError) as info:
        engine.suggest(query, "full", top=0)
    assert info.value.field == "top"
    with pytest.raises(SceneSuggestError) as info:
        EngineOptions(lambda2=float("nan"))
    assert info.value.field == "lambda2"
    assert len(engine.suggest(query, "full", top=3)) == 3


def test_a_candidate_that_does_not_fit_is_turned_to_its_next_best_heading(engine, study):
    from scenesuggest.suggestion.placement_checks import check_fit

    # 0.45 m from the right wall (x = 2.5): a 1.4 m wide desk facing +Z overhangs; turned by 90° it fits
    engine = engine.with_options()
    scores = engine.score(ContextQuery(study, "room", (2.05, 0.0, 0.3), (0, 1, 0)))
    i = engine.index["Desk"]
    learned = engine.heading_scores

    def heading_scores(scores, idx, faces):  # best at 0°, next at 90°, far apart
        out = learned(scores, idx, faces)
        out[idx == i] = -50.0
        out[idx == i, 0], out[idx == i, 9] = 0.0, -10.0
        return out

    engine.heading_scores = heading_scores
    faces, alphas, headings = engine.choose_poses(scores, "full")
    assert headings[i] == 0.0
    notes = [[] for _ in engine.names]
    fit = check_fit(engine, scores, faces, alphas, headings, np.tile(scores.prepared.point, (len(faces), 1)),
                    scores.total, notes, "full")
    assert fit.headings[i] == pytest.approx(math.pi / 2) and fit.notes[i] == ["turned 90° to fit"]
    assert fit.total[i] == scores.total[i]
    assert headings[i] == 0.0 and notes[i] == []  # the arguments are left as they were
    placed = poses.placement(scores.prepared.point, (0, 1, 0), faces[i], engine.size[i], fit.alphas[i])
    assert frames.world_bbox(placed, engine.size[i])[1][0] <= 2.5 + 1e-9


def test_collision_aware_placement_penalises_and_explains(engine, study):
    aware = engine.with_options(collision_aware=True)
    # in the corner nothing that large fits at any heading: the couch-in-the-corner case
    corner = ContextQuery(study, "room", (2.4, 0.0, 1.9), (0, 1, 0))
    plain = {s.category: s for s in engine.suggest(corner, "full")}
    checked = {s.category: s for s in aware.suggest(corner, "full")}
    assert checked["Desk"].score == pytest.approx(plain["Desk"].score * 0.5)
    assert any("overhangs Room 'room'" in n for n in checked["Desk"].notes)
    assert checked["PowerSocket"].score == plain["PowerSocket"].score  # small things fit anywhere
    # on the spot of the existing desk, a chair collides with it (basic mode only penalises)
    desk_obj = desk_of(study)
    basic = {s.category: s for s in aware.suggest(
        ContextQuery(study, "room", desk_obj.transform[:3, 3], (0, 1, 0)), "basic")}
    assert any(f"collides with Desk '{desk_obj.id}'" in n for n in basic["OfficeChair"].notes)


def test_anchor_refinement_moves_towards_the_typical_spot(engine, study):
    desk = desk_of(study)
    scene = study
    for child in study.children(desk.id):
        scene = scene.without(child.id)
    _, point = on_desk(scene, 0.0, 0.0)  # the monitor usually stands 20 cm further back
    refined = engine.with_options(anchor_refinement=True, refine_radius_m=0.25)
    monitor = next(s for s in refined.suggest(ContextQuery(scene, desk.id, point, (0, 1, 0))) if
                   s.category == "Monitor")
    local = frames.apply(np.linalg.inv(desk.transform), monitor.placement[:3, 3][None])[0]
    assert local[2] < -0.05 and monitor.notes and "moved" in monitor.notes[0]
    assert poses.is_horizontal((0, 1, 0))


def test_orientation_option_and_restricting_the_list(engine, study):
    with pytest.raises(SceneSuggestError) as info:
        EngineOptions(orientation="sideways")
    assert info.value.field == "orientation"
    query = ContextQuery(study, "room", (0.0, 0.0, 0.3), (0, 1, 0))
    learned = {s.category: s for s in engine.suggest(query, "full")}
    paper = {s.category: s for s in engine.with_options(orientation="paper").suggest(query, "full")}
    assert [s for s in learned] == [s for s in paper]  # ranking is the same; only the headings may differ
    # the office chair in front of the desk faces it (180°); the paper's rule orients some categories otherwise
    assert learned["OfficeChair"].heading_deg == pytest.approx(180.0)
    assert any(learned[c].heading_deg != paper[c].heading_deg for c in learned)
    only = engine.suggest(query, "full", top=2, only={"Speaker", "OfficeChair"})
    assert [s.category for s in only] == [c for c in learned if c in {"Speaker", "OfficeChair"}]
    assert [s.rank for s in only] == [1, 2]


def test_heading_evidence_is_the_same_whatever_the_engine_was_asked_before(corpus):
    """The log-densities kept per segment (Priors.segment_log_density) are those of their counts, returned as copies:
    an engine that answered other clicks first gives every click's heading evidence bit for bit as a fresh one."""
    from scenesuggest.learning.orientation import log_density
    from scenesuggest.suggestion import headings

    fresh = Engine(Priors.fit(corpus.scenes, corpus.taxonomy))
    warmed = Engine(Priors.fit(corpus.scenes, corpus.taxonomy))
    clicks = []
    for scene in corpus.scenes[:6]:
        desk, point = on_desk(scene, dx=0.1) if any(o.category == "Desk" for o in scene) else (None, None)
        if desk is not None:
            clicks.append(ContextQuery(scene, desk.id, point, (0, 1, 0)))
        clicks.append(ContextQuery(scene, "room", (1.0, 0.0, 1.0), (0, 1, 0)))
    for q in clicks[1:]:
        warmed.suggest(q, "full", top=5)
    every = np.arange(len(fresh.candidates))
    for q in clicks:
        a, b = fresh.score(q), warmed.score(q)
        faces = fresh.face_indices(a.prepared, "full", every)
        assert np.array_equal(headings.evidence(fresh, a.prepared, every, faces),
                              headings.evidence(warmed, b.prepared, every, faces))
    p = warmed.priors
    rows = np.flatnonzero(p._log_density_filled)
    assert len(rows) > 0
    counts = np.where((rows % 2 == 0)[:, None], p.seg_theta_n[rows // 2], p.seg_phi_n[rows // 2])
    kept = p.segment_log_density(rows)
    assert np.array_equal(kept, log_density(counts))
    kept[:] = 0.0  # a copy: the engine's own rows stay as they were
    assert np.array_equal(p.segment_log_density(rows), log_density(counts))
