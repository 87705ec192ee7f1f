"""Engines by name: the registry and its entry points, the frequency and learned engines (how a study's condition
names and serves one is in tests/test_study_engines.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import synthetic
from support import DEMO_FOLDER

from scenesuggest import engines
from scenesuggest.engines.learned import LearnedEngine
from scenesuggest.engines.learned import training as learned_training
from scenesuggest.engines.protocol import LoadContext, SuggestionEngine
from scenesuggest.errors import SceneSuggestError
from scenesuggest.learning.priors import Priors
from scenesuggest.suggestion.suggest import Engine

ROOT = Path(__file__).resolve().parents[3]


def test_the_built_in_engines_are_registered_and_described():
    assert engines.names()[:4] == ("paper", "learned", "frequency", "http")
    for name in ("paper", "learned", "frequency", "http"):
        kind = engines.kind(name)
        assert kind.name == name and kind.describe()["version"]
    assert engines.configure({}).name == "paper"  # a table without a name: today's keys, the paper's engine
    spec = engines.configure({"orientation": "paper", "lambda2": 0.5})
    assert spec.name == "paper" and spec.config.orientation == "paper" and spec.config.lambda2 == 0.5
    with pytest.raises(SceneSuggestError, match="unknown engine 'psychic': one of paper, learned, frequency, http"):
        engines.kind("psychic")


def test_every_built_in_engine_keeps_the_protocol(corpus, learned_file, tmp_path):
    priors_file = Priors.fit(corpus.scenes, corpus.taxonomy).save(tmp_path / "p.npz")
    scene = corpus.scenes[0]
    desk = next(o for o in scene if o.category == "Desk")
    query = synthetic_query(scene, desk)
    for table in ({"name": "paper"}, {"name": "frequency"}, {"name": "learned", "file": str(learned_file)}):
        engine = engines.load(engines.configure(table), LoadContext(priors_file))
        assert isinstance(engine, SuggestionEngine) and engine.name == table["name"]
        found = engine.suggest(query, "full", top=4, only={"Monitor", "Keyboard", "Speaker", "DeskLamp", "Bed"})
        assert found.engine == table["name"] and len(found) == 4 and found.fallback is None
        assert {s.category for s in found} <= {"Monitor", "Keyboard", "Speaker", "DeskLamp", "Bed"}
        for s in found:
            r = s.placement[:3, :3]
            assert np.allclose(r.T @ r, np.eye(3), atol=1e-9) and s.models == engine.categories[s.category]
        explained = engine.explain(query, "full", top=2, categories=["Bed"])
        totals = engine.score(query).total
        for e in explained:  # the explanation is of the score that ranks (SHAP values sum to it)
            assert e["score"] == pytest.approx(totals[engine.index[e["category"]]], rel=1e-6, abs=1e-9)
        assert [e["category"] for e in explained][:2] == [s.category for s in engine.suggest(query, "full", top=2)]
        assert explained[-1]["category"] == "Bed" and explained[-1]["contributions"]


def synthetic_query(scene, parent):
    """A click on the middle of ``parent``'s top, the scene as it is."""
    from scenesuggest.suggestion.query import ContextQuery

    lo, hi = parent.world_bbox()
    return ContextQuery(scene, parent.id, ((lo[0] + hi[0]) / 2, hi[1], (lo[2] + hi[2]) / 2), (0.0, 1.0, 0.0))


def test_the_frequency_engine_ranks_by_how_often_a_category_occurs(corpus, tmp_path):
    priors = Priors.fit(corpus.scenes, corpus.taxonomy)
    engine = engines.kind("frequency").from_priors(engines.configure({"name": "frequency"}).config, priors)
    scene = corpus.scenes[0]
    ranked = [s.category for s in engine.suggest(synthetic_query(scene, scene.objects["room"]), "basic")]
    paper = Engine(priors)
    by_rate = [paper.names[i] for i in np.lexsort((paper.name_order, -paper.base_rate))]
    assert ranked == by_rate  # whatever was clicked
    desk = next(o for o in scene if o.category == "Desk")
    assert [s.category for s in engine.suggest(synthetic_query(scene, desk), "basic")] == by_rate


def test_with_frames_the_learned_engine_turns_each_suggestion_as_its_frame_classifier_trusts_most(
        corpus, learned_file, tmp_path):
    """With ``frames = true`` every candidate's heading in full mode is that of the frame with the classifier's
    highest trust, the classifier asked about every frame (the engine leaves out the candidates whose frames all
    propose one heading); by default the heading is the paper engine's (the product of the evidence)."""
    from scenesuggest.engines.learned.features import frame_proposals

    table = {"name": "learned", "file": str(learned_file)}
    engine = engines.load(engines.configure({**table, "frames": True}), LoadContext(tmp_path / "priors.npz"))
    default = engines.load(engines.configure(table), LoadContext(tmp_path / "priors.npz"))
    assert engine.choose_frames and not default.choose_frames
    scene = corpus.scenes[0]
    every = np.arange(len(engine.candidates))
    agreeing = differ = 0
    for parent in (scene.objects["room"], next(o for o in scene if o.category == "Desk")):
        scores = engine.score(synthetic_query(scene, parent))
        faces = engine.face_indices(scores.prepared, "full", every)
        proposed, rows = frame_proposals(engine, scores, every, faces)
        trust = engine.frames.predict(rows.reshape(-1, rows.shape[-1])).reshape(proposed.shape)
        expected = proposed[every, np.argmax(trust, axis=1)]
        assert np.array_equal(engine.frame_headings(scores, every, faces)[1], expected)
        assert np.array_equal(engine.choose_poses(scores, "full", every)[2], expected)
        paper = Engine.choose_poses(engine, scores, "full", every)[2]
        assert np.array_equal(default.choose_poses(scores, "full", every)[2], paper)
        assert np.array_equal(engine.choose_poses(scores, "basic", every)[2], Engine.choose_poses(
            engine, scores, "basic", every)[2])  # basic keeps the canonical pose either way
        agreeing += int((proposed == proposed[:, :1]).all(axis=1).sum())
        differ += int((np.abs(expected - paper) > 1e-9).sum())
    assert 0 < agreeing < 2 * len(every)  # both kinds of candidate were asked about
    assert differ  # the classifier's choice is not the paper's everywhere, so the two settings were told apart
    for bad in ("yes", 1, None):
        with pytest.raises(SceneSuggestError, match="expected true or false") as info:
            engines.configure({**table, "frames": bad})
        assert info.value.field == "frames"
    plain = LearnedEngine(engine.priors, engine.stats, engine.ranker, None, engine.meta)  # no classifier: the product
    assert np.array_equal(plain.frame_headings(scores, every, faces)[1], proposed[:, 0])
    with pytest.raises(SceneSuggestError, match="no frame classifier") as info:
        plain.choosing_frames(True)  # asked for a classifier it lacks: said, not ignored
    assert info.value.field == "frames" and plain.choosing_frames(False) is plain


def test_the_learned_engine_is_deterministic_and_its_file_byte_stable(corpus, learned_file, tmp_path):
    again = learned_training.fit(corpus.scenes, corpus.taxonomy, seed=0).save(tmp_path / "again.npz")
    assert again.read_bytes() == learned_file.read_bytes()
    loaded = LearnedEngine.load(learned_file)
    assert loaded.save(tmp_path / "resaved.npz").read_bytes() == learned_file.read_bytes()
    other = learned_training.fit(corpus.scenes, corpus.taxonomy, seed=1).save(tmp_path / "seed1.npz")
    assert other.read_bytes() != learned_file.read_bytes()  # the seed decides the inner folds and the models
    meta = LearnedEngine.read_meta(learned_file)
    assert meta["format"] == "scenesuggest-learned" and meta["scenes"] == len(corpus.scenes) and meta["seed"] == 0


def test_the_learned_engines_rows_come_from_priors_that_never_saw_their_scene(corpus, monkeypatch):
    """Out of fold: every training row of a scene is computed from priors (and context counts) learned without
    that scene and without any near-copy of it."""
    from scenesuggest.corpora.folds import similar_groups

    groups = similar_groups(corpus.scenes)
    fitted_on: list[set[str]] = []
    asked: list[tuple[set[str], list[str]]] = []
    real_fit, real_rows = Priors.fit, learned_training.fold_rows

    def recording_fit(scenes, *args, **kwargs):
        scenes = list(scenes)
        fitted_on.append({s.id for s in scenes})
        return real_fit(scenes, *args, **kwargs)

    def recording_rows(engine, stats, scenes, periods):
        scenes = list(scenes)
        asked.append((fitted_on[-1], [s.id for s in scenes]))
        return real_rows(engine, stats, scenes, periods)

    monkeypatch.setattr(learned_training.Priors, "fit", recording_fit)
    monkeypatch.setattr(learned_training, "fold_rows", recording_rows)
    rows = learned_training.out_of_fold(corpus.scenes, corpus.taxonomy, 0, None, lambda items, label="": items)
    assert len(asked) == learned_training.INNER_FOLDS and rows.ranking
    group_of = {s.id: g for s, g in zip(corpus.scenes, groups, strict=True)}
    for trained, held in asked:
        assert not trained & set(held)
        assert not {group_of[s] for s in trained} & {group_of[s] for s in held}  # nor a near-copy
    assert sorted(s for _, held in asked for s in held) == sorted(s.id for s in corpus.scenes)


def test_a_damaged_or_foreign_learned_file_is_named(learned_file, tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(SceneSuggestError) as info:
        LearnedEngine.load(bad)
    assert info.value.file == str(bad)
    priors_like = tmp_path / "priors.npz"
    Priors.fit(synthetic.corpus(n_study=4, n_bedroom=2).scenes).save(priors_like)
    with pytest.raises(SceneSuggestError, match="not a learned engine's file"):
        LearnedEngine.load(priors_like)


# --- engines of other packages ---------------------------------------------------------------------------------
PLUGIN = '''
"""An engine of another package: the paper's ranking, reversed — it knows nothing but the protocol."""
from scenesuggest.engines.paper import KIND as PAPER
from scenesuggest.engines.protocol import EngineKind, LoadContext
from scenesuggest.suggestion.suggest import SuggestionList


class Reversed:
    name = "reversed"

    def __init__(self, inner):
        self.inner = inner
        self.categories = inner.categories

    def suggest(self, query, mode="full", top=None, only=None):
        found = self.inner.suggest(query, mode, None, only)
        flipped = tuple(reversed(found.suggestions))[:top]
        return SuggestionList(flipped, found.surface_type, found.scene_type, found.parent_category, self.name)


class ReversedKind(EngineKind):
    name = "reversed"
    version = "7"
    summary = "the paper's ranking, upside down"
    trainable = True

    def configure(self, options, base=None):
        if set(options) - {"loud"}:
            from scenesuggest.errors import SceneSuggestError
            raise SceneSuggestError("unknown key", field=sorted(set(options) - {"loud"})[0])
        return dict(options)

    def load(self, config, context: LoadContext):
        return Reversed(PAPER.load(PAPER.configure({}), context))

    def fit(self, config, scenes, taxonomy, *, seed=0, progress=None, periods=None):
        return Reversed(PAPER.fit(PAPER.configure({}), scenes, taxonomy))


KIND = ReversedKind()
'''


def plugin_path(tmp_path: Path) -> Path:
    """A package installed beside ours (a folder on the path with its dist-info), adding the engine 'reversed'."""
    site = tmp_path / "site"
    (site / "reversed_engine").mkdir(parents=True)
    (site / "reversed_engine" / "__init__.py").write_text(textwrap.dedent(PLUGIN))
    info = site / "reversed_engine-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: reversed-engine\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[scenesuggest.engines]\nreversed = reversed_engine:KIND\n")
    return site


def run_cli(args: list[str], site: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT)])}
    return subprocess.run([sys.executable, "-m", "scenesuggest.cli", *args], capture_output=True, text=True, env=env)


def test_a_package_installed_beside_ours_adds_an_engine(tmp_path):
    from scenesuggest.corpora.native import write_native

    site = plugin_path(tmp_path)
    listed = json.loads(run_cli(["engine", "list", "--json"], site).stdout)["engines"]
    assert {"name": "reversed", "version": "7", "summary": "the paper's ranking, upside down",
            "trainable": True} in listed
    # a study names it (validated by the plugin), and evaluate compares it on the same folds
    study = (tmp_path / "demo")
    import shutil

    shutil.copytree(DEMO_FOLDER, study)
    text = (study / "study.toml").read_text()
    (study / "study.toml").write_text(text.replace('engine = { orientation = "learned" }',
                                                   'engine = { name = "reversed", volume = 11 }'))
    proc = run_cli(["study", "validate", str(study / "study.toml")], site)
    assert proc.returncode == 2 and "conditions[2].engine.volume" in proc.stderr, proc.stderr
    out = write_native(synthetic.corpus(n_study=6, n_bedroom=4), tmp_path / "c")
    proc = run_cli(["evaluate", f"json:{out}", "--folds", "2", "--engine", "paper", "--engine", "reversed",
                    "--resamples", "100", "--json"], site)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    paper, flipped = result["engines"]["paper"], result["engines"]["reversed"]
    assert flipped["version"] == "7" and flipped["modes"]["full"]["mrr"] < paper["modes"]["full"]["mrr"]
    assert flipped["vs_first"]["high"] < 0 and flipped["vs_first"]["engine"] == "paper"


def test_a_plugin_may_not_take_a_built_in_name(tmp_path):
    site = plugin_path(tmp_path)
    info = site / "reversed_engine-1.0.dist-info" / "entry_points.txt"
    info.write_text("[scenesuggest.engines]\npaper = reversed_engine:KIND\n")
    proc = run_cli(["engine", "list", "--json"], site)
    listed = {e["name"]: e for e in json.loads(proc.stdout)["engines"]}
    assert "taken by another package" in listed["paper"]["error"]


# --- a study condition that names its engine -------------------------------------------------------------------


def test_suggest_explains_why_each_category_got_its_rank(corpus, learned_file, tmp_path):
    from scenesuggest.scenes import scene_json

    scene = corpus.scenes[0]
    keyboard = next(o for o in scene if o.category == "Keyboard")
    scene_file = tmp_path / "scene.json"
    scene_json.save(scene.without(keyboard.id), scene_file)
    point = ",".join(str(v) for v in keyboard.contact_point)
    priors_file = Priors.fit(corpus.scenes, corpus.taxonomy).save(tmp_path / "p.npz")
    for engine, trained in (("paper", priors_file), ("learned", learned_file)):
        args = [sys.executable, "-m", "scenesuggest.cli", "suggest", "--engine", engine, "--priors", str(trained),
                "--scene", str(scene_file), "--parent", keyboard.parent, "--point", point, "--normal", "0,1,0",
                "--top", "2", "--explain", "--category", "Bed"]
        proc = subprocess.run([*args, "--json"], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        out = json.loads(proc.stdout)
        explained = {e["category"]: e for e in out["explanations"]}
        assert out["engine"] == engine and "Bed" in explained and len(explained) == 3
        for e in explained.values():  # the largest first, and with the baseline they sum to the score
            sizes = [abs(c["contribution"]) for c in e["contributions"] if c["value"] is not None]
            assert sizes and sizes == sorted(sizes, reverse=True)
            total = e["baseline"] + sum(c["contribution"] for c in e["contributions"])
            assert total == pytest.approx(e["score"], rel=1e-6, abs=1e-9)
        human = subprocess.run(args, capture_output=True, text=True).stdout
        assert "why (each category's score" in human and "Bed" in human
    proc = subprocess.run([*args[:-1], "Unicorn"], capture_output=True, text=True)
    assert proc.returncode == 2 and "field 'category': the engine has no category 'Unicorn'" in proc.stderr


def test_the_learned_engine_ranks_a_shortlist_with_every_tree(learned_file, monkeypatch):
    """The first trees pick the shortlist; it is ranked by every tree and placed above the rest, which keep the
    first trees' order (tested with a shortlist of 4 of the synthetic corpus' categories)."""
    from scenesuggest.engines.learned import engine as module

    engine = LearnedEngine.load(learned_file)
    monkeypatch.setattr(module, "SHORTLIST", 4)
    rows = np.random.default_rng(0).normal(size=(len(engine.candidates), len(module.RANKING))).astype(np.float32)
    rows[:, module.RANKING.index("surface_type")] = 0
    rows[:, module.RANKING.index("scene_type")] = 0
    total = engine._rank(rows)
    first = engine.ranker.predict(rows, num_iteration=module.SHORTLIST_TREES)
    full = engine.ranker.predict(rows)
    short = np.argsort(-first, kind="stable")[:4]
    rest = np.setdiff1d(np.arange(len(rows)), short)
    assert np.allclose(total[short], full[short]) and total[rest].max() < total[short].min()
    assert list(np.argsort(-total[rest], kind="stable")) == list(np.argsort(-first[rest], kind="stable"))


def test_explanations_sum_to_the_score_inside_and_outside_the_shortlist(corpus, learned_file, monkeypatch):
    from scenesuggest.engines.learned import engine as module

    engine = LearnedEngine.load(learned_file)
    monkeypatch.setattr(module, "SHORTLIST", 4)
    scene = corpus.scenes[0]
    query = synthetic_query(scene, next(o for o in scene if o.category == "Desk"))
    last = engine.suggest(query, "basic")[-1].category  # ranked last: outside a shortlist of 4
    explained = {e["category"]: e for e in engine.explain(query, top=2, categories=[last])}
    assert [e["shortlisted"] for e in explained.values()] == [True, True, False]
    assert explained[last]["contributions"][-1]["feature"] == "below the shortlist"
    for e in explained.values():
        total = e["baseline"] + sum(c["contribution"] for c in e["contributions"])
        assert total == pytest.approx(e["score"], rel=1e-6, abs=1e-9)


def test_every_fold_numbers_the_scene_types_alike(corpus, monkeypatch):
    from scenesuggest.engines.learned.context import ContextStats

    seen = []
    real = ContextStats.fit.__func__

    def recording(cls, scenes, names, scene_types=None):
        stats = real(cls, scenes, names, scene_types)
        seen.append(stats.scene_types)
        return stats

    monkeypatch.setattr(ContextStats, "fit", classmethod(recording))
    few = [s for s in corpus.scenes if s.scene_type == "Study"][:5] + [s for s in corpus.scenes
                                                                        if s.scene_type == "Bedroom"][:1]
    learned_training.fit(few, corpus.taxonomy, seed=0)
    assert len(seen) >= 3 and all(types == ["Bedroom", "Study"] for types in seen)
