"""Learning the priors from a corpus: the counts behind every learned array of
:class:`scenesuggest.learning.priors.Priors` but the orientation weights, phase by phase.

1. vocabulary — the categories present (and :data:`~scenesuggest.learning.observations.WALL`) with their taxonomy
   ancestors, and the *entities* that statistics are kept for: each category, the subtree (``Chair/*``) of each category
   that has subcategories, and the POOLED entity;
2. occurrence — per (parent entity, scene type) the histogram of how many children of each entity a parent
   instance carries, giving ``P(|C on p| > k)``;
3. support surface, attachment face and canonical turn — counts per (entity, surface type[, face[, 10° bin]]);
4. model table — each model's category, canonical box size and supported instances;
5. relative position and orientation — pair priors per group and child (:mod:`scenesuggest.learning.pair_priors`).

Every observation counts for each entity of its category (the category and the subtrees above it) and for its
scene type and all scene types (``*``). Nothing here reads a ``Priors``: the orientation weights are learned
last, from a provisional ``Priors`` built on these arrays (:func:`scenesuggest.learning.orientation.learn_orientation`).
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass

import numpy as np

from ..scenes.frames import FACES
from ..scenes.scene import SURFACE_TYPES, Scene
from ..scenes.taxonomy import MIN_OBSERVATIONS, Taxonomy
from .angle_bins import angle_bins
from .observations import POOLED, WALL, Pair, Support, corpus_observations
from .orientation import BINS
from .pair_priors import Expanded, expand_pairs, pair_arrays

#: The scene type that stands for all scene types (the last scene index).
ANY = "*"
#: Child counts of K_MAX or more share the last histogram bin.
K_MAX = 8


def subtree(category: str) -> str:
    """The entity of a category's whole subtree."""
    return f"{category}/*"


@dataclass(frozen=True)
class Counts:
    """What counting a corpus yields: the learned ``arrays`` and ``meta`` of the priors (all but the orientation
    weights, and without the file's format fields) and the observations the orientation weights are learned
    from: support records, pair records, pairs expanded over entities and scene types, and ``expand``
    (category → its entities, specific first)."""

    arrays: dict[str, np.ndarray]
    meta: dict
    supports: list[Support]
    pairs: list[Pair]
    expanded: Expanded
    expand: dict[str, list[int]]


def learn_counts(scenes: list[Scene], taxonomy: Taxonomy, progress) -> Counts:
    """Count every prior of ``scenes`` (world frame) but the orientation weights, with ``taxonomy`` for
    back-off; ``progress(items, label)`` wraps the long loops."""
    categories, tax, entities, expand = vocabulary(scenes, taxonomy)
    types = scene_types(scenes)
    s_index = {s: i for i, s in enumerate(types)}
    n_e = len(entities)
    arrays = occurrence(scenes, expand, s_index, n_e, progress)
    supports, pairs = corpus_observations(scenes)
    arrays.update(support_counts(supports, expand, n_e))
    expanded = expand_pairs(pairs, expand, s_index, len(types) - 1, pooled=n_e - 1)
    arrays.update(pair_arrays(expanded, progress))
    model_ids, models = model_table(supports, categories)
    arrays.update(models)
    meta = {"categories": categories, "entities": entities, "scene_types": types, "model_ids": model_ids,
            "taxonomy": tax.to_dict(), "scenes": len(scenes), "scene_ids": sorted(s.id for s in scenes),
            "supports": len(supports), "k_max": K_MAX, "bins": BINS, "min_observations": MIN_OBSERVATIONS}
    return Counts(arrays, meta, supports, pairs, expanded, expand)


def vocabulary(scenes: list[Scene], taxonomy: Taxonomy) -> tuple[list[str], Taxonomy, list[str], dict]:
    """(categories, taxonomy restricted to them, entities, category → its entities, specific first)."""
    present = sorted({o.category for s in scenes for o in s} | {WALL})
    categories = sorted(set(present) | {a for c in present for a in taxonomy.ancestors(c)})
    parents = {c: taxonomy.parent(c) for c in categories if taxonomy.parent(c) in set(categories)}
    tax = Taxonomy(parents)
    has_children = set(parents.values())
    entities = list(categories) + [subtree(c) for c in categories if c in has_children] + [POOLED]
    entity_index = {e: i for i, e in enumerate(entities)}
    expand = {c: [entity_index[c]] + [entity_index[subtree(x)] for x in [c, *tax.ancestors(c)]
                                      if subtree(x) in entity_index] for c in categories}
    return categories, tax, entities, expand


def scene_types(scenes: list[Scene]) -> list[str]:
    """The scene types of the corpus, sorted, then ANY (all of them)."""
    return sorted({s.scene_type for s in scenes} - {ANY}) + [ANY]


def occurrence(scenes: list[Scene], expand: dict, s_index: dict, n_e: int, progress) -> dict[str, np.ndarray]:
    """Child-count histograms per (parent entity, scene type) → P(|C on p| > k)."""
    n_s = len(s_index)
    any_s = n_s - 1
    parent_n = np.zeros((n_e, n_s), dtype=np.float64)
    hist: dict[tuple[int, int], np.ndarray] = {}
    for scene in progress(scenes, "counting children"):
        children = defaultdict(Counter)
        for o in scene:
            if o.parent is not None:
                children[o.parent].update(expand[o.category])
        for p in scene:
            keys = [(e, s) for e in expand[p.category] for s in {s_index[scene.scene_type], any_s}]
            for e, s in keys:
                parent_n[e, s] += 1
                for child, count in children[p.id].items():
                    h = hist.setdefault((e * n_s + s, child), np.zeros(K_MAX + 1))
                    h[min(count, K_MAX)] += 1
    occ_items = sorted(hist.items())
    occ_pgt = np.zeros((len(occ_items), K_MAX + 1), dtype=np.float32)
    for i, ((key, _), h) in enumerate(occ_items):
        n = parent_n[key // n_s, key % n_s]
        occ_pgt[i] = (h[::-1].cumsum()[::-1] - h) / n  # P(count > k) for k = 0..K_MAX
    return {"occ_parent_n": parent_n.astype(np.float32),
            "occ_key": np.array([k for (k, _), _ in occ_items], dtype=np.int32),
            "occ_child": np.array([c for (_, c), _ in occ_items], dtype=np.int32), "occ_pgt": occ_pgt}


def support_counts(supports: list[Support], expand: dict, n_e: int) -> dict[str, np.ndarray]:
    """Supported instances per entity and surface type (``sup_counts``), per face (``att_counts``) and per 10°
    bin of the turn from the canonical pose (``alpha_n``)."""
    sup_counts = np.zeros((n_e, len(SURFACE_TYPES)), dtype=np.float32)
    att_counts = np.zeros((n_e, len(SURFACE_TYPES), len(FACES)), dtype=np.float32)
    alpha_n = np.zeros((n_e, len(SURFACE_TYPES), len(FACES), BINS), dtype=np.float32)
    alpha_bins = angle_bins(np.array([sup.alpha for sup in supports]))
    for sup, b in zip(supports, alpha_bins, strict=True):
        t, f = SURFACE_TYPES.index(sup.surface_type), FACES.index(sup.face)
        for e in expand[sup.category]:
            sup_counts[e, t] += 1
            att_counts[e, t, f] += 1
            if b >= 0:
                alpha_n[e, t, f, b] += 1
    return {"sup_counts": sup_counts, "att_counts": att_counts, "alpha_n": alpha_n}


def model_table(supports: list[Support], categories: list[str]) -> tuple[list[str], dict[str, np.ndarray]]:
    """(model ids, their arrays): models sorted by category, most used first; each model's category index,
    canonical box size (metres) and supported instances, and the categories that have models."""
    model_counts: Counter = Counter()
    model_info: dict[str, tuple[str, tuple]] = {}
    for sup in supports:
        model_counts[sup.model_id] += 1
        model_info[sup.model_id] = (sup.category, sup.size)
    model_ids = sorted(model_counts, key=lambda m: (model_info[m][0], -model_counts[m], m))
    c_index = {c: i for i, c in enumerate(categories)}
    return model_ids, {
        "model_category": np.array([c_index[model_info[m][0]] for m in model_ids], dtype=np.int32),
        "model_size": np.array([model_info[m][1] for m in model_ids], dtype=np.float32).reshape(-1, 3),
        "model_count": np.array([model_counts[m] for m in model_ids], dtype=np.int32),
        "candidate_categories": np.array(sorted({c_index[model_info[m][0]] for m in model_ids}), dtype=np.int32),
    }
