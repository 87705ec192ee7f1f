"""The SceneSuggest replication (experiments/scenesuggest-2015) on the real Stanford corpus: its model corpus, its
six target scenes, priors without the targets' source scenes, a study file that loads, simulated participants who
complete it, and the comparison with the paper."""

from __future__ import annotations

import itertools
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from demostudy import make_app
from support import REPLICATION, ROOT, SHARED_DATA, replication_module

from scenesuggest.corpora.representatives import read_representatives, top_representatives
from scenesuggest.errors import SceneSuggestError
from scenesuggest.learning.priors import Priors
from scenesuggest.library.index import load_index
from scenesuggest.scenes import poses, scene_json

PREPARED = ROOT / "var" / "experiments" / "scenesuggest-2015"
REPRESENTATIVES = SHARED_DATA / "stanford_models" / "representatives.tsv"


@pytest.fixture(scope="module")
def targets():
    return replication_module("targets")


@pytest.fixture(scope="module")
def models(stanford):
    return {category: stanford.models[model_id] for category, model_id in read_representatives(REPRESENTATIVES)}


def test_representatives_file_and_the_rule_agree(stanford):
    listed = read_representatives(REPRESENTATIVES)
    assert len(listed) == 100 and all(stanford.models[m].mesh is not None for _, m in listed)
    chosen = top_representatives(stanford, 100)
    # only the listed models have meshes here, so the rule can only pick among them; two listed categories
    # fall into one of ours (RoundTable and CoffeeTable are both CoffeeTable), hence 99
    assert len(chosen) == 99 and len({c for c, _ in chosen}) == 99
    assert {m for _, m in chosen} <= {m for _, m in listed}


def test_a_bad_representatives_file_names_file_and_line(tmp_path):
    bad = tmp_path / "representatives.tsv"
    bad.write_text("category\tmodel_id\nDesk\n")
    with pytest.raises(SceneSuggestError, match=r"representatives.tsv:2: expected"):
        read_representatives(bad)
    bad.write_text("name,id\n")
    with pytest.raises(SceneSuggestError, match=r":1: expected a header"):
        read_representatives(bad)


def test_targets_are_small_supported_scenes_with_walls_and_turns(targets, models, stanford):
    wall_scenes, turn_scenes = 0, 0
    for target_id, (_, source) in targets.TARGETS.items():
        scene = targets.compose(target_id, models, stanford.taxonomy)
        objects = [o for o in scene if o.parent is not None]
        if source is not None:
            assert 5 <= len(objects) <= 10, target_id
        room_lo, room_hi = scene.objects["room"].world_bbox()
        for o in objects:
            lo, hi = o.world_bbox()
            assert (lo >= room_lo - 1e-6).all() and (hi <= room_hi + 1e-6).all(), (target_id, o.id)
            if o.parent != "room":  # stands within its parent's top, on it
                plo, phi = scene.objects[o.parent].world_bbox()
                assert plo[0] - 1e-6 <= lo[0] and hi[0] <= phi[0] + 1e-6 and plo[2] - 1e-6 <= lo[2] and \
                    hi[2] <= phi[2] + 1e-6, (target_id, o.id)
                assert lo[1] == pytest.approx(phi[1], abs=1e-6)
        for a, b in itertools.combinations(objects, 2):
            if b.parent == a.id or a.parent == b.id:
                continue
            (alo, ahi), (blo, bhi) = a.world_bbox(), b.world_bbox()
            assert not (np.minimum(ahi, bhi) - np.maximum(alo, blo) > 0.01).all(), (target_id, a.id, b.id)
        walls = [o for o in objects if abs(o.contact_normal[1]) < 0.1]
        for o in walls:  # flat against a wall, upright
            lo, hi = o.world_bbox()
            assert min(abs(lo[0] - room_lo[0]), abs(hi[0] - room_hi[0]), abs(lo[2] - room_lo[2]),
                       abs(hi[2] - room_hi[2])) < 1e-6 and o.transform[1, 1] == pytest.approx(1.0)
        turns = [abs(math.degrees(poses.turn_about(poses.attach_rotation(o.attachment_face, o.contact_normal),
                                                     o.transform[:3, :3], o.contact_normal))) for o in objects]
        wall_scenes += bool(walls) and source is not None
        turn_scenes += any(t > 45 for t in turns) and source is not None
    assert wall_scenes >= 2 and turn_scenes >= 2


def test_prepare_builds_library_priors_and_targets(replication, targets):
    manifest = json.loads((PREPARED / "manifest.json").read_text())
    assert manifest["held_out"] == targets.held_out() and len(targets.held_out()) == 6
    assert manifest["representatives"].endswith("representatives.tsv") and manifest["models"] == 100
    priors = Priors.load(PREPARED / "priors.npz")
    assert priors.meta["scenes"] == manifest["scenes_in_corpus"] - 6 == manifest["training_scenes"]
    assert not set(targets.held_out()) & set(priors.meta["scene_ids"])
    library = load_index(PREPARED / "library")
    built = {m.id for m in library.values() if m.asset}
    assert len(built) == 100 and all((PREPARED / "library" / library[m].asset).is_file() for m in built)
    for target_id in targets.TARGETS:
        scene = scene_json.load(PREPARED / "scenes" / f"{target_id}.json")
        assert {o.model_id for o in scene if o.parent is not None} <= built


@pytest.mark.slow
def test_engines_on_the_targets_trained_two_ways(replication, tmp_path):
    """The comparison's per-engine table: each engine trained without the targets' sources and on all 133 scenes
    (files kept and trained again only when what they come from changed), asked the same queries."""
    import shutil

    compare = replication_module("compare")
    prepared = tmp_path / "prepared"
    # what `make replication` may have trained and run there already is left behind: this test trains its own
    shutil.copytree(PREPARED, prepared, ignore=shutil.ignore_patterns("library", "run", "*-all.npz", "engines.json"))
    (prepared / "library").symlink_to(PREPARED / "library")
    said: list[str] = []
    trained = compare.trained_engines(prepared, ("paper", "frequency"), log=said.append)
    assert set(trained) == {"held_out", "all"} and said == [f"training the paper engine on 133 scenes → "
                                                           f"{prepared / 'priors-all.npz'} …"]
    assert Priors.load(prepared / "priors-all.npz").meta["scenes"] == 133
    compare.trained_engines(prepared, ("paper", "frequency"), log=said.append)
    assert len(said) == 1  # kept
    rows = compare.engines_on_targets(prepared, trained)
    assert len(rows) == 45 and all(r["held_out.paper.rank"] for r in rows)
    held = [r["held_out.paper.rank"] for r in rows]
    assert held == [r["rank"] for r in compare.engine_on_targets(prepared)]  # the study's own engine, as before
    assert np.mean([1 / r["all.paper.rank"] for r in rows]) > np.mean([1 / r for r in held])  # the sources help
    text = "\n".join(compare.engine_lines(rows, trained))
    assert "Trained on all 133 scenes" in text and "| paper MRR | rank 1 | worst | turn | frequency MRR" in text


def test_extra_models_join_the_library_only_with_a_mesh(stanford):
    prepare = replication_module("prepare")
    reps = read_representatives(REPRESENTATIVES)
    assert len(prepare.library_models(stanford, reps, [])) == 100
    assert "room01" in prepare.library_models(stanford, reps, ["room01"])  # a room shell has a mesh here
    without_mesh = next(m for m in stanford.models.values() if m.mesh is None)
    with pytest.raises(SceneSuggestError, match="no mesh"):
        prepare.library_models(stanford, reps, [without_mesh.id])
    with pytest.raises(SceneSuggestError, match="no model 'nope'"):
        prepare.library_models(stanford, reps, ["nope"])


def test_prepare_names_a_missing_corpus(tmp_path, monkeypatch):
    monkeypatch.delenv("SCENESUGGEST_STANFORD_DIR", raising=False)
    run = subprocess.run([sys.executable, str(REPLICATION / "prepare.py"), "--out", str(tmp_path)],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "SCENESUGGEST_STANFORD_DIR" in run.stderr and "Traceback" not in run.stderr
    run = subprocess.run([sys.executable, str(REPLICATION / "prepare.py"), "--stanford-dir", str(tmp_path),
                          "--out", str(tmp_path / "out")], capture_output=True, text=True)
    assert run.returncode == 2 and "no scenes/ folder" in run.stderr and not (tmp_path / "out").exists()


def test_the_study_file_loads_with_two_periods_in_a_williams_design(replication):
    from study_server.studies.served import StudyRuntime
    from study_server.studies.study_file import load_study

    study = load_study(replication)
    StudyRuntime(study).validate_scenes()  # every target parses
    assert study.design == "williams" and study.n_rows == 12 and len(study.periods) == 2
    plans = [study.plan(row) for row in range(study.n_rows)]
    for plan in plans:
        trials = [t for t in plan if t.kind == "trial"]
        assert len(trials) == 9 and len({(t.condition, t.scene) for t in trials}) == 9
    surveys = {q.id for q in study.exit_survey}
    assert {"enjoy_list", "competent_list", "enjoy_suggestions", "competent_suggestions", "preference"} <= surveys


@pytest.mark.slow
def test_simulated_participants_complete_the_replication(replication, tmp_path):
    from simulation.run import simulate

    app = make_app(tmp_path, studies=[replication])
    report = simulate(3, seed=1, app=app, study="scenesuggest-2015")
    assert report["completed"] == 3 and report["trials"] == 27, report
    from study_server.base.extensions import db
    from study_server.base.models import Trial

    with app.app_context():  # every trial's events rebuild the scene the bot submitted, close to its target
        done = db.session.query(Trial).filter(Trial.done_at.isnot(None)).all()
        assert len(done) == 30 and {t.replay for t in done} == {"match"}
        assert min(t.score for t in done) > 0.8, sorted(t.score for t in done)


def test_the_learned_engine_variant_changes_the_suggestion_conditions_only(replication, tmp_path):
    """The study ``make replication`` runs again with the learned engine: the same study (id, scenes, design,
    resources) with ``basic`` and ``full`` served by the learned engine, written anywhere."""
    import tomllib

    compare = replication_module("compare")
    learned = tmp_path / "learned.npz"
    variant = tomllib.loads(compare.learned_variant(replication, learned))
    original = tomllib.loads(replication.read_text())
    engines = {c["id"]: c.get("engine") for c in variant["conditions"]}
    assert engines == {"none": None, "basic": {"name": "learned", "file": str(learned)},
                       "full": {"name": "learned", "file": str(learned)}}
    assert variant["id"] == original["id"] and variant["design"] == original["design"]
    for key in ("priors", "library"):
        assert variant["resources"][key] == str((replication.parent / original["resources"][key]).resolve())
    assert [s["target"] for s in variant["scenes"]] == [
        str((replication.parent / s["target"]).resolve()) for s in original["scenes"]]
    with pytest.raises(SystemExit, match="basic and full"):
        bad = tmp_path / "study.toml"
        bad.write_text(replication.read_text().replace('id = "full"', 'id = "oriented"'))
        compare.learned_variant(bad, learned)


def _at_paper(**changes) -> dict:
    """A simulated run whose every cell is the paper's (a zero-width interval), with ``changes`` (measure →
    condition → mean)."""
    from simulation.paper_tables import CONDITIONS, TABLE1, TABLE2

    sim = {m: {c: by[c][0] for c in CONDITIONS} for m, by in TABLE1.items()}
    sim |= {f"rank_{label}": dict(by) for label, by in TABLE2.items()}
    for measure, by in changes.items():
        sim[measure] = {**sim[measure], **by}
    out = {m: tuple({"mean": v[c], "low": v[c], "high": v[c]} for c in CONDITIONS) for m, v in sim.items()}
    return out | {"_n": {"participants": {"completed": 20}}}


def test_folds_side_by_side_mark_what_each_was_fitted_on(tmp_path, monkeypatch):
    compare = replication_module("compare")
    monkeypatch.setattr(compare, "CALIBRATIONS", tmp_path)
    fitted = {"loss": 12.5, "loss_without_prior": 10.0, "evaluations": 350, "seconds": 700.0, "converged": False,
              "free": ["hesitation_s"], "parameters": {}, "measured": {}}
    (tmp_path / "basic+full.json").write_text(json.dumps({**fitted, "on": ["basic", "full"]}))
    slow_none = compare.fold_summary("basic+full", _at_paper(total_time={"none": 150.0}))
    cells = {(r["measure"], r["condition"]): r for r in slow_none["cells"]}
    assert {r["role"] for r in slow_none["cells"] if r["condition"] == "none"} == {"predicted"}
    assert not cells["total_time", "none"]["matched"] and cells["mrr", "none"]["matched"]
    assert slow_none["matched"] == {"calibrated": [18, 18], "predicted": [8, 9]}
    found = {d["finding"].split(":")[0]: d["reproduced"] for d in slow_none["directions"]}
    assert found == {"H1": False, "H2": True, "H3": True, "MRR": True}  # none 150 s is not slower than basic 170 s
    lines = "\n".join(compare.fold_lines([slow_none], None))
    assert "| 1 | Total time (s) | none | 204.0 [177.0, 241.0] | 150.0 [150.0, 150.0] ✗ |" in lines
    assert "| 1 | Total time (s) | basic | 170.0 [130.0, 267.0] | 170.0 [170.0, 170.0] *fit* |" in lines
    assert "| basic+full | 12.5 (10.0) | 350, 700 s | 18 of 18 | 8 of 9 | H2, H3, MRR |" in lines
    (tmp_path / "none+full.json").write_text(json.dumps({**fitted, "on": ["none"]}))
    with pytest.raises(SystemExit, match="fitted on \\['none'\\], not on \\['none', 'full'\\]"):
        compare.fold_summary("none+full", _at_paper())
