"""The contextual priors of SceneSuggest, learned from a corpus (:mod:`scenesuggest.learning.counts` counts them), as
plain arrays.

* occurrence — per (parent, scene type): for each child category C the histogram of how many children of
  C each parent instance carries, giving ``P(|C on p| > k)``;
* support surface ``P_sup(t | C)`` and attachment face ``P_att(f | C, t)`` — counts;
* relative position and orientation — per (C, C_ref, scene type, relation, surface type): a KDE of offsets
  and counts of θ and φ (:mod:`scenesuggest.learning.pair_priors`); walls are references too
  (:mod:`scenesuggest.learning.observations`);
* the canonical orientation prior — counts of the turn from the canonical pose per (C, surface type, face);
* how far ``full`` mode trusts each kind of orientation evidence — weights per category
  (:mod:`scenesuggest.learning.orientation`).

Position densities are divided by their peak, so each is a relative likelihood in [0, 1] and comparable
with the probabilities of the occurrence term. The paper's orientation rule reads ``seg_hist``: the θ counts
smoothed with a (1, 2, 1) kernel and divided by their peak.

Back-off, as in the paper, is by category: statistics are kept for *entities* — a category itself
(``Chair``) and, for categories with subcategories, its whole subtree (``Chair/*``). A category with
fewer than 5 instances reads the statistics of the first ancestor subtree that has 5 (:meth:`Priors.
stat_entity`). Statistics keyed by scene type climb the taxonomy within the query's scene type first
(a chest of drawers in a bedroom reads the bedroom statistics of all chests of drawers) and only then
use all scene types (``*``) (:meth:`Priors.keyed_entity`); what is borrowed from other scene types counts
fully for categories seen in the query's scene type at least once and by UNSEEN_IN_SCENE_TYPE for the
others, and a category never seen on a parent or next to a reference in the query's scene type reads the
statistics of all scene types, weighted likewise — a soft prior, so that what never happens in bedrooms
is held back there but stays reachable where the context supports it (:meth:`Priors.borrowed`,
:meth:`Priors.occurrence_table`, :meth:`Priors.pair_sources`). When nothing is observed the engine falls back
to geometry.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from functools import cached_property
from pathlib import Path

import numpy as np

from ..atomic import write_atomically
from ..corpora.folds import similar_groups
from ..digest import ENGINE_SOURCES, source_digest
from ..errors import SceneSuggestError
from ..npz import npz_bytes, read_npz
from ..scenes import frames
from ..scenes.scene import SURFACE_TYPES, Scene
from ..scenes.taxonomy import MIN_OBSERVATIONS, Taxonomy
from .counts import ANY, K_MAX, learn_counts, subtree
from .observations import POOLED, RELATIONS
from .orientation import BINS, KINDS, learn_orientation, log_density, smooth

FORMAT = "scenesuggest-priors"
VERSION = 2
#: Statistics borrowed from all scene types count this much for a category never seen in the query's scene type
#: or never seen next to a reference or on a parent there (chosen by held-out MRR on near-copy-grouped folds:
#: Stanford 0.234 with a hard mask (0), 0.239 at 0.2, 0.237 at 0.5; AI2-THOR 0.492 at 0 and at 0.2; on folds of
#: another seed, not used to choose, 0.234 and 0.238).
UNSEEN_IN_SCENE_TYPE = 0.2
FACES = frames.FACES
__all__ = ["ANY", "BINS", "FACES", "K_MAX", "Priors", "UNSEEN_IN_SCENE_TYPE", "code_digest", "peak_normalised"]


def code_digest() -> str:
    """A short hash of the engine's code (every module of the package and its corpus loaders), which decides
    what a priors file holds: prepared priors files are retrained when it changes."""
    return source_digest(*ENGINE_SOURCES)


class Priors:
    """Learned state, as plain arrays, plus the lookups the engine needs. Build with :meth:`fit` or
    :meth:`load`; :meth:`save` writes the arrays of the Attributes section and ``meta``, nothing else.

    Entities are the categories, then the subtrees (``Chair/*``), then POOLED; scene types are sorted, then
    ``*`` (all of them); surface types and faces are in the order of ``SURFACE_TYPES`` and ``FACES``; angle bins
    are 10° wide (BINS of them). Counts are of supported instances in the training scenes.

    Attributes
    ----------
    occ_parent_n : ndarray of shape (entities, scene types), float32
        Parent instances per parent entity and scene type.
    occ_key : ndarray of shape (rows,), int32
        Occurrence rows: parent entity × scene types + scene index, sorted.
    occ_child : ndarray of shape (rows,), int32
        Occurrence rows: child entity.
    occ_pgt : ndarray of shape (rows, K_MAX + 1), float32
        P(count of the child on the parent > k), k = 0..K_MAX.
    sup_counts : ndarray of shape (entities, surface types), float32
        Supported instances per surface type.
    att_counts : ndarray of shape (entities, surface types, faces), float32
        Supported instances per surface type and attachment face.
    alpha_n : ndarray of shape (entities, surface types, faces, BINS), float32
        Turns from the canonical pose, counts per 10° bin.
    group_keys : ndarray of shape (groups, 4), int32
        Pair groups: reference entity, scene index, relation, surface type.
    seg_group : ndarray of shape (segments,), int32
        Each segment's group (segments sorted by group, then child).
    seg_child : ndarray of shape (segments,), int32
        Each segment's child entity.
    seg_start : ndarray of shape (segments,), int64
        First sample of the segment in ``pair_xy``.
    seg_count : ndarray of shape (segments,), int32
        Samples of the segment.
    seg_bandwidth : ndarray of shape (segments, 2), float32
        KDE bandwidth per axis, metres.
    seg_weight : ndarray of shape (segments,), float32
        1 / the KDE's peak value, so the density is a relative likelihood in [0, 1].
    seg_theta_n : ndarray of shape (segments, BINS), float32
        Counts of θ (heading relative to the reference's front) per 10° bin.
    seg_phi_n : ndarray of shape (segments, BINS), float32
        Counts of φ (heading relative to the bearing to the reference) per 10° bin.
    pair_xy : ndarray of shape (samples, 2), float32
        Offsets δ, metres, in the reference's frame on the support plane.
    orient_weights : ndarray of shape (entities, surface types, kinds), float32
        Trust (≥ 0) in each kind of orientation evidence, in the order of ``orientation.KINDS``.
    model_category : ndarray of shape (models,), int32
        Category index of each model (models in the order of ``meta["model_ids"]``).
    model_size : ndarray of shape (models, 3), float32
        Canonical box size, metres.
    model_count : ndarray of shape (models,), int32
        Supported instances of the model.
    candidate_categories : ndarray of shape (candidates,), int32
        Category indices that have models, sorted.

    Derived on construction (not saved): ``categories``, ``entities``, ``scene_types``, ``model_ids`` and
    ``taxonomy`` from ``meta``; ``seg_hist`` (segments, BINS), the paper's peak-normalised smoothed θ histograms.
    """

    #: The learned arrays, as documented under Attributes: saved and loaded as they are.
    ARRAY_NAMES = ("occ_parent_n", "occ_key", "occ_child", "occ_pgt", "sup_counts", "att_counts", "alpha_n",
                   "group_keys", "seg_group", "seg_child", "seg_start", "seg_count", "seg_bandwidth", "seg_weight",
                   "seg_theta_n", "seg_phi_n", "pair_xy", "orient_weights", "model_category", "model_size",
                   "model_count", "candidate_categories")

    def __init__(self, arrays: dict[str, np.ndarray], meta: dict):
        missing = set(self.ARRAY_NAMES) - set(arrays)
        if missing:
            raise SceneSuggestError(f"priors lack {', '.join(sorted(missing))}", field="arrays")
        self.meta = meta
        self.arrays = a = {name: arrays[name] for name in self.ARRAY_NAMES}
        self.occ_parent_n, self.occ_key, self.occ_child, self.occ_pgt = (
            a["occ_parent_n"], a["occ_key"], a["occ_child"], a["occ_pgt"])
        self.sup_counts, self.att_counts, self.alpha_n = a["sup_counts"], a["att_counts"], a["alpha_n"]
        self.group_keys, self.seg_group, self.seg_child = a["group_keys"], a["seg_group"], a["seg_child"]
        self.seg_start, self.seg_count, self.seg_bandwidth = a["seg_start"], a["seg_count"], a["seg_bandwidth"]
        self.seg_weight, self.seg_theta_n, self.seg_phi_n = a["seg_weight"], a["seg_theta_n"], a["seg_phi_n"]
        self.pair_xy, self.orient_weights = a["pair_xy"], a["orient_weights"]
        self.model_category, self.model_size, self.model_count = (
            a["model_category"], a["model_size"], a["model_count"])
        self.candidate_categories = a["candidate_categories"]
        self.categories: list[str] = meta["categories"]
        self.entities: list[str] = meta["entities"]
        self.scene_types: list[str] = meta["scene_types"]
        self.model_ids: list[str] = meta["model_ids"]
        self.taxonomy = Taxonomy(meta["taxonomy"])
        self.entity_index = {e: i for i, e in enumerate(self.entities)}
        self.scene_index = {s: i for i, s in enumerate(self.scene_types)}
        self.seg_hist = peak_normalised(self.seg_theta_n)
        self._groups = {tuple(int(v) for v in key): g for g, key in enumerate(self.group_keys)}
        self._occ_starts = np.searchsorted(self.occ_key, np.arange(len(self.entities) * len(self.scene_types) + 1))
        self._chains: dict[str, list[int]] = {}
        self._keyed: dict[tuple[str, int], tuple[int, int]] = {}
        # log_density of each segment's θ (row 2s) and φ (row 2s + 1) counts, filled as queries need them; the OS
        # commits memory only for the pages of rows filled (about 14 rows a page)
        self._log_density = np.empty((2 * len(self.seg_theta_n), BINS))
        self._log_density_filled = np.zeros(2 * len(self.seg_theta_n), dtype=bool)
        self._group_seg_starts = np.searchsorted(self.seg_group, np.arange(len(self.group_keys) + 1))

    # the kernel density's inputs in float64, made on the first query (not for priors only trained or saved)
    @cached_property
    def sample_xy(self) -> np.ndarray:
        """(samples, 2) ``pair_xy`` in float64."""
        return self.pair_xy.astype(float)

    @cached_property
    def seg_inv_bandwidth(self) -> np.ndarray:
        """(segments, 2) 1 / ``seg_bandwidth``, in float64."""
        return 1.0 / self.seg_bandwidth.astype(float)

    @cached_property
    def seg_weight64(self) -> np.ndarray:
        """(segments,) ``seg_weight`` in float64."""
        return self.seg_weight.astype(float)

    @cached_property
    def alpha_log_density(self) -> np.ndarray:
        """(entities, surface types, faces, BINS) :func:`~scenesuggest.learning.orientation.log_density` of
        ``alpha_n``, in float64: the canonical evidence of every heading bin."""
        return log_density(self.alpha_n)

    def segment_log_density(self, rows: np.ndarray) -> np.ndarray:
        """(len(rows), BINS) log-probabilities of the heading bins (:func:`~scenesuggest.learning.orientation.
        log_density`) from the θ counts of segment s (row 2s) or its φ counts (row 2s + 1), a copy; each row is
        computed once (pure, so threads that fill one row at once write the same values, and a row's flag is set
        only after its values)."""
        todo = rows[~self._log_density_filled[rows]]
        if len(todo):
            todo = np.unique(todo)  # siblings of one category share their segments
            counts = np.where((todo % 2 == 0)[:, None], self.seg_theta_n[todo // 2], self.seg_phi_n[todo // 2])
            self._log_density[todo] = log_density(counts)
            self._log_density_filled[todo] = True
        return self._log_density[rows]

    # --- vocabulary and back-off -------------------------------------------------------------------------
    def entity_chain(self, category: str) -> list[int]:
        """Entities from specific to general: the category, its subtree, then its ancestors' subtrees (memoised
        for the categories the priors know, a bounded set; the list is shared, not to be changed)."""
        chain = self._chains.get(category)
        if chain is None:
            chain = self._entity_chain(category)
            if chain:
                self._chains[category] = chain
        return chain

    def _entity_chain(self, category: str) -> list[int]:
        chain = []
        if category in self.entity_index:
            chain.append(self.entity_index[category])
        for c in [category, *self.taxonomy.ancestors(category)]:
            e = self.entity_index.get(subtree(c))
            if e is not None:
                chain.append(e)
        return chain

    # --- construction --------------------------------------------------------------------------------------
    @classmethod
    def fit(cls, scenes: Iterable[Scene], taxonomy: Taxonomy | None = None,
            progress: Callable[[Iterable, str], Iterable] | None = None, orientation_kinds: tuple[str, ...] = KINDS,
            orientation_trust: str = "learned") -> Priors:
        """Learn every prior from ``scenes`` (world frame) with ``taxonomy`` for back-off: the counts
        (:func:`scenesuggest.learning.counts.learn_counts`), then the orientation weights, learned from priors that
        trust every kind alike. ``orientation_kinds`` and ``orientation_trust`` restrict the orientation evidence, for
        ablations (:func:`scenesuggest.learning.orientation.learn_orientation`)."""
        scenes, kinds = list(scenes), tuple(orientation_kinds)
        counts = learn_counts(scenes, taxonomy or Taxonomy(), progress or (lambda items, label="": items))
        meta = {"format": FORMAT, "version": VERSION, "code": code_digest(), **counts.meta,
                "orientation_kinds": list(kinds), "orientation_trust": orientation_trust}
        flat = np.ones((len(meta["entities"]), len(SURFACE_TYPES), 1), dtype=np.float32)
        untrusted = cls({**counts.arrays, "orient_weights": flat}, meta)
        weights = learn_orientation(untrusted, counts.supports, counts.pairs, counts.expanded, similar_groups(scenes),
                                    counts.expand, kinds, orientation_trust)
        return cls({**counts.arrays, "orient_weights": weights}, meta)

    # --- persistence ---------------------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write one ``.npz`` file, whole or not at all (a running server may read it); saving what was loaded
        reproduces the file byte for byte."""
        return write_atomically(path, npz_bytes(self.payload()))

    def payload(self) -> dict[str, np.ndarray]:
        """What :meth:`save` writes: the arrays and ``meta`` (JSON as bytes)."""
        return {**self.arrays, "meta": np.frombuffer(json.dumps(self.meta, sort_keys=True).encode(), dtype=np.uint8)}

    @classmethod
    def load(cls, path: str | Path) -> Priors:
        """Read a priors file; a file that is not one, or of another version, is an error naming the file."""
        path = Path(path)
        payload = read_npz(path, what="priors")
        try:
            return cls.from_payload(payload, path)
        except (ValueError, KeyError) as e:
            raise SceneSuggestError(f"cannot read priors: {e}", file=str(path)) from None

    @classmethod
    def from_payload(cls, payload: dict[str, np.ndarray], path: str | Path) -> Priors:
        """Priors from what :meth:`payload` gave (read from ``path``, named in errors), checked as :meth:`load`
        checks a file."""
        meta = _checked_meta(payload, Path(path))
        return cls({k: v for k, v in payload.items() if k != "meta"}, meta)

    @staticmethod
    def read_meta(path: str | Path) -> dict:
        """The metadata of a priors file, checked as :meth:`load` checks it, without reading the arrays."""
        path = Path(path)
        return _checked_meta(read_npz(path, ("meta",), "priors"), path)

    # --- lookups -------------------------------------------------------------------------------------------
    def stat_entity(self, category: str, backoff: bool = True) -> int | None:
        """The entity whose statistics stand for ``category``: the category itself when it has at least 5
        instances, else the first ancestor subtree that has (else the best observed; None if unknown)."""
        chain = self.entity_chain(category)
        if not chain:
            return None
        if not backoff:
            return chain[0]
        counts = [float(self.occ_parent_n[e, -1]) for e in chain]
        for e, n in zip(chain, counts, strict=True):
            if n >= MIN_OBSERVATIONS:
                return e
        return chain[int(np.argmax(counts))]

    def keyed_entity(self, category: str, scene_type: str | None, backoff: bool = True) -> tuple[int, int] | None:
        """(entity, scene index) for statistics keyed by scene type: the first of the category's chain with
        at least 5 instances in the scene type; failing that, its statistics entity over all scene types.
        Without back-off: the category itself in the scene type (all types if the type is unknown)."""
        chain = self.entity_chain(category)
        if not chain:
            return None
        any_s = len(self.scene_types) - 1
        s = self.scene_index.get(scene_type, any_s) if scene_type not in (None, ANY) else any_s
        if not backoff:
            return chain[0], s
        memo = (category, s)  # a known category and a known scene type: a bounded set
        key = self._keyed.get(memo)
        if key is None:
            counts = self.occ_parent_n[chain, s]
            found = [e for e, n in zip(chain, counts.tolist(), strict=True) if n >= MIN_OBSERVATIONS]
            key = self._keyed[memo] = (found[0], s) if found else (self.stat_entity(category), any_s)
        return key

    def occurrence_key(self, parent_category: str, scene_type: str | None, backoff: bool = True) -> int | None:
        """The (parent entity, scene type) row block to read P(|C on p| > k) from; None for a parent
        category never seen."""
        key = self.keyed_entity(parent_category, scene_type, backoff)
        if key is None or self.occ_parent_n[key] == 0:
            return None
        return key[0] * len(self.scene_types) + key[1]

    def occurrence_rows(self, key: int) -> tuple[np.ndarray, np.ndarray]:
        """(child entities, P(>k) rows of length K_MAX+1) observed under an occurrence key."""
        a, b = self._occ_starts[key], self._occ_starts[key + 1]
        return self.occ_child[a:b], self.occ_pgt[a:b]

    def group_for(self, ref_category: str, scene_type: str | None, relation: str, surface_type: str,
                  backoff: bool = True) -> int | None:
        """The pair-prior group of a reference (its entity, scene type, relation, surface type)."""
        key = self.keyed_entity(ref_category, scene_type, backoff)
        if key is None:
            return None
        return self._groups.get((*key, RELATIONS.index(relation), SURFACE_TYPES.index(surface_type)))

    def segments(self, group: int) -> tuple[np.ndarray, np.ndarray]:
        """(child entities, segment indices) of a pair-prior group, sorted by child entity."""
        a, b = self._group_seg_starts[group], self._group_seg_starts[group + 1]
        return self.seg_child[a:b], np.arange(a, b)

    def borrowed(self, entities: np.ndarray, scene_index: int, scene_type: str | None) -> np.ndarray | float:
        """How far statistics read under ``scene_index`` count for ``entities`` in a ``scene_type`` query: fully
        when they come from the query's own type, or from all types (``*``) for entities seen in it; by
        UNSEEN_IN_SCENE_TYPE for entities never seen in it."""
        s = self.scene_index.get(scene_type) if scene_type is not None else None
        if scene_index != len(self.scene_types) - 1 or s is None or s == scene_index:
            return 1.0
        return np.where(self.occ_parent_n[entities, s] > 0, 1.0, UNSEEN_IN_SCENE_TYPE)

    def occurrence_table(self, parent_category: str, scene_type: str | None, backoff: bool = True
                         ) -> np.ndarray | None:
        """(entities, K_MAX + 1) P(|C on p| > k) for a parent in a scene type, None for a parent never seen.

        The scene type is a soft prior: a child the parent never carried in this scene type reads the parent's
        statistics over all scene types, weighted by UNSEEN_IN_SCENE_TYPE; when the scene type has no statistics
        of the parent at all, all scene types stand in (weighted by :meth:`borrowed`)."""
        key = self.occurrence_key(parent_category, scene_type, backoff)
        if key is None:
            return None
        n_s = len(self.scene_types)
        dense = np.zeros((len(self.entities), K_MAX + 1))
        if key % n_s != n_s - 1:
            wide = self.occurrence_key(parent_category, None, backoff)
            if wide is not None:
                children, rows = self.occurrence_rows(wide)
                dense[children] = UNSEEN_IN_SCENE_TYPE * rows.astype(float)
            children, rows = self.occurrence_rows(key)
            dense[children] = rows
            return dense
        children, rows = self.occurrence_rows(key)
        dense[children] = rows
        return dense * np.asarray(self.borrowed(np.arange(len(self.entities)), n_s - 1, scene_type)).reshape(-1, 1)

    def pair_sources(self, entities: np.ndarray, ref_category: str, scene_type: str | None, relation: str,
                     surface_type: str, backoff: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """For each of ``entities`` (the statistics entities of candidate categories): the segment that holds
        its statistics next to a reference of ``ref_category`` (−1 where there is none) and how far they count.

        The query's scene type first; an entity never seen next to this reference in it reads the statistics of
        all scene types, weighted by UNSEEN_IN_SCENE_TYPE (the scene type is a soft prior, never a hard mask);
        when the scene type has no statistics of this reference (in this relation, on this surface type), all
        scene types stand in, weighted by :meth:`borrowed`. Walls: an entity seen at one fewer than
        MIN_OBSERVATIONS times reads the statistics of every category at walls (the POOLED entity)."""
        entities = np.asarray(entities, dtype=np.int64)
        seg = np.full(len(entities), -1, dtype=np.int64)
        trust = np.zeros(len(entities))
        g = self.group_for(ref_category, scene_type, relation, surface_type, backoff)
        wide = self.group_for(ref_category, None, relation, surface_type, backoff)
        if g is not None and int(self.group_keys[g][1]) != len(self.scene_types) - 1:  # the room type's own
            self._fill(g, entities, seg, trust, np.ones(len(entities)))
            missing = seg < 0
            if wide is not None and missing.any():
                sub_seg, sub_trust = seg[missing], trust[missing]
                self._fill(wide, entities[missing], sub_seg, sub_trust,
                           np.full(int(missing.sum()), UNSEEN_IN_SCENE_TYPE))
                seg[missing], trust[missing] = sub_seg, sub_trust
        elif wide is not None:
            weight = self.borrowed(entities, len(self.scene_types) - 1, scene_type)
            self._fill(wide, entities, seg, trust, np.broadcast_to(weight, entities.shape))
        if relation == "wall" and wide is not None:
            few = (seg < 0) | (self.seg_theta_n[np.maximum(seg, 0)].sum(axis=1) < MIN_OBSERVATIONS)
            pooled_seg, pooled_trust = np.full(1, -1), np.zeros(1)
            self._fill(wide, np.array([self.entity_index[POOLED]]), pooled_seg, pooled_trust, np.ones(1))
            seg[few], trust[few] = pooled_seg[0], pooled_trust[0]
        seg[trust <= 0] = -1
        return seg, trust

    def _fill(self, group: int, entities: np.ndarray, seg: np.ndarray, trust: np.ndarray, weight: np.ndarray):
        """Write into ``seg`` and ``trust`` the segments of ``entities`` found in ``group``, with ``weight``."""
        children, segs = self.segments(group)
        if not len(children) or not len(entities):
            return
        pos = np.minimum(np.searchsorted(children, entities), len(children) - 1)
        found = children[pos] == entities
        seg[found] = segs[pos[found]]
        trust[found] = weight[found]

    def pair_segments(self, entities: np.ndarray, ref_category: str, scene_type: str | None, relation: str,
                      surface_type: str, backoff: bool = True) -> np.ndarray:
        """The segments of :meth:`pair_sources`."""
        return self.pair_sources(entities, ref_category, scene_type, relation, surface_type, backoff)[0]

    def describe(self) -> dict:
        return {"scenes": self.meta["scenes"], "supports": self.meta["supports"], "pairs": int(len(self.pair_xy)),
                "categories": len(self.categories), "candidates": int(len(self.candidate_categories)),
                "entities": len(self.entities), "groups": int(len(self.group_keys)),
                "segments": int(len(self.seg_group)), "scene_types": self.scene_types[:-1]}


# --- derived ---------------------------------------------------------------------------------------------------
def peak_normalised(counts: np.ndarray) -> np.ndarray:
    """Histogram counts (…, BINS) smoothed with the (1, 2, 1)/4 kernel and divided by their peak; flat (all
    ones) where nothing was counted."""
    h = smooth(np.asarray(counts, dtype=np.float64))
    peak = h.max(axis=-1, keepdims=True)
    return np.where(peak > 0, h / np.where(peak > 0, peak, 1.0), 1.0).astype(np.float32)


def _checked_meta(data, path: Path) -> dict:
    """The metadata entry of an open ``.npz`` (or of its arrays by name): present, JSON, this format and this
    engine's version."""
    if "meta" not in (data.files if hasattr(data, "files") else data):
        raise SceneSuggestError("not a priors file (no metadata)", file=str(path), field="meta")
    try:
        meta = json.loads(data["meta"].tobytes().decode())
    except (UnicodeDecodeError, ValueError):
        raise SceneSuggestError("not a priors file (bad metadata)", file=str(path), field="meta") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise SceneSuggestError("not a priors file", file=str(path), field="format")
    if meta.get("version") != VERSION:
        raise SceneSuggestError(f"priors file has version {meta.get('version')!r}, this engine reads "
                                f"version {VERSION}: retrain with 'scenesuggest priors train'",
                                file=str(path), field="version")
    return meta
