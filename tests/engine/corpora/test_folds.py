"""Held-out folds: near-copies of a scene stay in one fold; distinct scenes are spread evenly."""

import numpy as np
import synthetic

from scenesuggest.corpora.folds import folds_of, grouped_folds, similar_groups, similarity


def test_variants_of_one_arrangement_are_grouped_and_never_split():
    scenes = synthetic.corpus().scenes  # studies and bedrooms jittered from two arrangements
    share = similarity(scenes)
    assert share.shape == (len(scenes), len(scenes)) and np.all(np.diag(share) == 0)
    groups = similar_groups(scenes)
    # the synthetic models are per category (like AI2-THOR's per-type models): not distinctive, so only
    # objects of the same category at the same place make scenes near-copies
    assert 2 <= len(set(groups)) < len(scenes) and max(np.bincount(groups)) > 1
    folds = grouped_folds(groups, 4, seed=0)
    assert sorted(np.concatenate(folds).tolist()) == list(range(len(scenes)))
    for g in set(groups):
        members = {i for i, x in enumerate(groups) if x == g}
        assert sum(bool(members & set(f.tolist())) for f in folds) == 1


def test_grouped_folds_are_balanced_and_reproducible():
    groups = [0, 0, 0, 1, 2, 3, 4, 4, 5, 6, 7, 8]
    folds = grouped_folds(groups, 3, seed=1)
    assert [len(f) for f in folds] == [4, 4, 4]
    assert [f.tolist() for f in folds] == [f.tolist() for f in grouped_folds(groups, 3, seed=1)]
    assert [len(f) for f in folds_of(23, 5, seed=3)] == [5, 5, 5, 4, 4]


def test_stanford_near_copies_and_ai2thor_rooms(stanford, ai2thor):
    groups = similar_groups(stanford.scenes)
    sizes = np.bincount(groups)
    assert sizes.max() <= 20 and (sizes > 1).sum() >= 15  # many small families of variants, no giant one
    assert sum(sizes[sizes > 1]) >= len(stanford.scenes) // 2
    # AI2-THOR's models are per object type: sharing them does not make two rooms near-copies
    assert len(set(similar_groups(ai2thor.scenes))) >= 190
