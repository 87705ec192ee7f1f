"""Offline evaluation: rank semantics, the fold protocol, and what each prior buys."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
import synthetic

from scenesuggest.corpora.corpus import Corpus
from scenesuggest.errors import SceneSuggestError
from scenesuggest.evaluation.evaluate import evaluate, folds_of, rank_of, summary
from scenesuggest.evaluation.formatting import format_evaluation


def test_rank_of_counts_ties_half():
    scores = np.array([0.5, 0.9, 0.5, 0.1])
    assert rank_of(scores, 1) == 1.0
    assert rank_of(scores, 0) == 2.5  # tied with one other for places 2 and 3
    assert rank_of(scores, 3) == 4.0
    assert rank_of(scores, None) == math.inf
    among = np.array([True, False, True, True])  # the 0.9 may not be suggested
    assert rank_of(scores, 0, among) == 1.5 and rank_of(scores, 3, among) == 3.0
    assert rank_of(scores, 1, among) == math.inf
    s = summary([1.0, 2.0, math.inf, 5.0])
    assert s["mrr"] == pytest.approx((1 + 0.5 + 0 + 0.2) / 4) and s["top1"] == 0.25 and s["top5"] == 0.75


def test_folds_partition_the_scenes():
    folds = folds_of(23, 5, seed=3)
    assert sorted(np.concatenate(folds).tolist()) == list(range(23))
    assert [len(f) for f in folds] == [5, 5, 5, 4, 4]
    assert [f.tolist() for f in folds] == [f.tolist() for f in folds_of(23, 5, seed=3)]


def test_evaluation_on_a_synthetic_corpus():
    result = evaluate(synthetic.corpus(), folds=4, seed=0)
    assert result["queries"] == 12 * 8 + 8 * 3 + 4  # every support edge of every scene
    full, base = result["modes"]["full"], result["baselines"]
    assert set(base) == {"frequency", "parent_only", "no_backoff", "no_position"}
    assert full["mrr"] > 0.9 > base["frequency"]["mrr"]
    assert full["orient_within_45"] > 0.9
    # folded by symmetry: at least as good as unfolded; the chairs face their desks, the canonical pose does not
    for pose in (full, full["paper"], full["canonical"]):
        assert {"orient_folded_within_15", "orient_folded_within_45", "orient_median_deg"} <= set(pose)
        assert pose["orient_folded_within_45"] >= pose["orient_folded_within_15"]
    assert full["orient_folded_within_45"] > full["canonical"]["orient_folded_within_45"]
    chairs = result["chairs_at_tables"]
    assert chairs["n"] == 12 and chairs["full_facing_within_45"] == 1.0 > chairs["canonical_facing_within_45"]
    assert result["categories"]["OfficeChair"]["n"] == 12
    plain_full = result["ungrouped"]["modes"]["full"]
    assert {"mrr", "orient_folded_within_45", "canonical", "paper"} <= set(plain_full)
    text = format_evaluation(result, by_category=True)
    assert "MRR" in text and "OfficeChair" in text and "near-copies kept together" in text
    plain = evaluate(synthetic.corpus(), folds=4, seed=0, group_similar=False)
    assert "ungrouped" not in plain and plain["grouping"]["group_similar"] is False
    # by default the room type is inferred from what is left (a study whose only desk is asked about is a plain
    # Room then); 'given' reads the scene's own type, which its desk made a Study
    assert plain["scene_type"] == "inferred" and "room types inferred without the object" in format_evaluation(plain)
    given = evaluate(synthetic.corpus(), folds=4, seed=0, group_similar=False, scene_type="given")
    assert given["scene_type"] == "given" and given["queries"] == plain["queries"]
    assert "as the corpus gives them" in format_evaluation(given)
    # (which rooms each reading gives a desk's query: test_suggestable; the synthetic desks rank first either way)
    with pytest.raises(SceneSuggestError, match="one of inferred, given"):
        evaluate(synthetic.corpus(), folds=4, scene_type="guessed")


@pytest.mark.slow
def test_what_each_prior_buys_on_the_stanford_corpus(stanford):
    """A quick two-fold run on 60 scenes: the full score beats P(C | parent) alone, which beats frequency."""
    corpus = Corpus(stanford.source, stanford.scenes[:60], stanford.models, stanford.taxonomy)
    result = evaluate(corpus, folds=2, seed=0)
    full, base = result["modes"]["full"]["mrr"], result["baselines"]
    assert full > base["no_position"]["mrr"] > base["frequency"]["mrr"]
    assert full > base["parent_only"]["mrr"]
    assert 0 < result["modes"]["full"]["orient_within_15"] <= result["modes"]["full"]["orient_within_45"] <= 1


def test_evaluate_command(tmp_path):
    from scenesuggest.corpora.native import write_native

    out = write_native(synthetic.corpus(n_study=6, n_bedroom=4), tmp_path / "c")
    proc = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "evaluate", f"json:{out}", "--folds", "2",
                           "--json"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["folds"] == 2 and {"basic", "full"} <= set(result["modes"])
    assert {"mrr", "top1", "top5", "orient_within_15", "orient_within_45", "orient_folded_within_15",
            "orient_folded_within_45", "orient_median_deg", "canonical"} <= set(result["modes"]["full"])
    assert set(result["modes"]["full"]["canonical"]) >= {"orient_folded_within_15", "orient_folded_within_45",
                                                          "orient_median_deg"}
    assert result["categories"] and all("full_folded_within_45" in c for c in result["categories"].values())
    proc = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "evaluate", f"json:{out}", "--folds", "2",
                           "--by-category", "--no-group-similar"], capture_output=True, text=True)
    assert proc.returncode == 0 and "folded ≤45°" in proc.stdout and "canonical" in proc.stdout
    proc = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "evaluate", f"json:{out}", "--folds", "20"],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "cannot make 20 folds" in proc.stderr


@pytest.mark.slow
def test_the_learned_engine_turns_as_the_papers_and_its_frame_classifiers_choice_is_reported_beside():
    """By default the learned engine's headings are the paper engine's (the same records, query by query); its frame
    classifier's choice is measured beside (``frames``), and is what ``frames = true`` turns by."""
    from scenesuggest.engines import configure

    corpus = synthetic.corpus()
    specs = [configure({"name": "paper"}), configure({"name": "learned"}), configure({"name": "learned",
                                                                                     "frames": True})]
    result = evaluate(corpus, folds=4, seed=0, engines=specs[:2], group_similar=False)
    paper, learned = (result["engines"][n]["modes"]["full"] for n in ("paper", "learned"))
    for key in ("orient_folded_within_15", "orient_folded_within_45", "orient_median_deg"):
        assert learned[key] == paper[key]
    assert "frames" in learned and "frame_oracle" in learned and "frames" not in paper
    rows = format_evaluation(result).splitlines()
    header = next(r for r in rows if r.startswith("engine "))
    row = next(r for r in rows if r.startswith("learned "))
    column = header.index("frames") + len("frames")  # right-aligned under its header
    assert row[column - 8:column] == f"{100 * learned['frames']['orient_folded_within_45']:>7.1f}%"
    framed = evaluate(corpus, folds=4, seed=0, engines=[specs[2]], group_similar=False)["modes"]["full"]
    assert framed["frames"] == learned["frames"] and framed["orient_folded_within_45"] == \
        learned["frames"]["orient_folded_within_45"]
