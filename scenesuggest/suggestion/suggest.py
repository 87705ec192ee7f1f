"""Contextual queries: a click on a surface → ranked categories, each placed (and, in ``full`` mode, oriented).

Score of a category C for a click on parent p (category P) in a scene of type s, on a surface of type t::

    w = λ1 · P(|C on p| > k) · P_sup(t | C)  +  λ2 · Σ_{r ∈ siblings ∪ parent} P_relpos(δ_r | C, C_r, s, R_r, t)

with k the children of C already on p, δ_r the click's offset from reference r, and each P_relpos a KDE
divided by its peak and by the number of references, so that the sum, like the first term, lies in
[0, 1] (see :mod:`scenesuggest.learning.priors`). λ1 = 1, λ2 = 0.25 by default. A category whose statistics are backed
off to an ancestor's subtree takes its share of the occurrence and position terms (its instances / the
subtree's), so rare siblings under one ancestor do not each inherit the ancestor's full evidence.

Placement: ``basic`` attaches the face that geometry suggests and keeps the canonical heading (α = 0);
``full`` attaches F = argmax_f P_att(f | C, t) and turns the object to a heading about the surface normal
chosen by the orientation option:

* ``learned`` (the default): the weighted product of orientation experts of :mod:`scenesuggest.learning.orientation` —
  the canonical pose, the fronts of and bearings to the parent and the siblings, the nearest wall — with trust
  learned per category, keeping the canonical heading when the evidence does not single out another;
* ``paper``: the heading h (10° steps, linearly interpolated histograms) that maximises
  Σ_r P_relpos(δ_r) · P_relori(h − h_r), each reference's histogram of θ weighted by how typical the click's
  position is relative to it (the paper's rule).

Headings and placements are computed only for the suggestions returned (``top``). Beyond the paper, each off
unless :class:`EngineOptions` turns it on: collision- and size-aware placement, anchor refinement, and
scene-type inference from the objects present.

The query, and what the engine reads from it before scoring (surface type, scene type, references), is
:mod:`scenesuggest.suggestion.query`.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from ..errors import SceneSuggestError
from ..learning.observations import is_radial
from ..learning.orientation import decide
from ..learning.priors import ANY, BINS, FACES, K_MAX, Priors
from ..scenes import frames, poses
from ..scenes.scene import SURFACE_TYPES
from . import headings
from .placement_checks import check_fit, refine_anchors
from .query import ContextQuery, Prepared, prepare
from .suggestable import suggestable, suggestable_mask

MODES = ("basic", "full")
ORIENTATIONS = ("learned", "paper")
HEADINGS = np.arange(BINS) * (2 * math.pi / BINS)


@dataclass(frozen=True)
class EngineOptions:
    """Weights and switches. The paper's conditions use the defaults; a study file may turn extras on, or
    choose the paper's orientation rule (``orientation = "paper"``)."""

    lambda1: float = 1.0
    lambda2: float = 0.25
    backoff: bool = True
    orientation: str = "learned"
    collision_aware: bool = False
    collision_penalty: float = 0.5
    anchor_refinement: bool = False
    refine_radius_m: float = 0.25
    infer_scene_type: bool = False

    def __post_init__(self):
        for name in ("lambda1", "lambda2", "collision_penalty", "refine_radius_m"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
                raise SceneSuggestError(f"must be a finite number ≥ 0, got {v!r}", field=name)
        if self.orientation not in ORIENTATIONS:
            raise SceneSuggestError(f"must be one of {', '.join(ORIENTATIONS)}, got {self.orientation!r}",
                                    field="orientation")


@dataclass(frozen=True)
class Suggestion:
    rank: int
    category: str
    score: float
    terms: dict[str, float]
    placement: np.ndarray  # 4×4, canonical → world
    attachment_face: str
    heading_deg: float
    models: tuple[str, ...]
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {"rank": self.rank, "category": self.category, "score": self.score, "terms": self.terms,
                "placement": frames.to_column_major(self.placement), "attachment_face": self.attachment_face,
                "heading_deg": self.heading_deg, "models": list(self.models), "notes": list(self.notes)}


@dataclass(frozen=True)
class SuggestionList(Sequence):
    """The answer to one query: its suggestions, best first, and what the engine read from the click — the
    surface type, the scene type and the clicked parent's category; which engine answered (its registry name)
    and, when an engine could not answer and another stood in, why (``fallback``). Behaves as the sequence of
    suggestions."""

    suggestions: tuple[Suggestion, ...]
    surface_type: str
    scene_type: str
    parent_category: str
    engine: str = "paper"
    fallback: str | None = None

    def __getitem__(self, i):
        return self.suggestions[i]

    def __len__(self) -> int:
        return len(self.suggestions)

    def to_dict(self) -> dict:
        return {"surface_type": self.surface_type, "scene_type": self.scene_type,
                "parent_category": self.parent_category, "engine": self.engine, "fallback": self.fallback,
                "suggestions": [s.to_dict() for s in self.suggestions]}


@dataclass
class Scores:
    """Per-candidate terms of one query (arrays over :attr:`Engine.candidates`); ``densities``: for each
    reference of :attr:`Prepared.references`, every candidate's P_relpos (scaled as in the position term)."""

    prepared: Prepared
    occurrence: np.ndarray
    surface: np.ndarray
    position: np.ndarray
    total: np.ndarray
    densities: list[np.ndarray] = field(default_factory=list)
    #: An engine that ranks by more than the paper's score keeps it here (and its own rows in ``features``).
    paper_total: np.ndarray | None = None
    features: np.ndarray | None = None


class Resolution(NamedTuple):
    """One reference key (reference category, scene type, relation, surface type) resolved for every candidate
    (:meth:`Engine.resolve`): the KDE samples of the candidates' relative positions, and each candidate's pair
    segment of the priors."""

    #: (samples, 2) offsets from the reference on the support plane, in its frame (metres).
    xy: np.ndarray
    #: (samples,) 1 / the sample's kernel bandwidth (1/metres).
    inv_bandwidth: np.ndarray
    #: (samples,) the sample's weight: its segment's weight × the back-off trust of its candidate.
    weight: np.ndarray
    #: (samples,) the candidate (engine index) each sample belongs to.
    owner: np.ndarray
    #: (candidates,) each candidate's pair segment of the priors, −1 where it has none.
    segment: np.ndarray


class Engine:
    """Answers context queries from a :class:`Priors` (the ``paper`` engine of :mod:`scenesuggest.engines`).
    Pure: answers depend only on priors and query. Everything below is derived from the priors and the options
    once, at construction; candidates are indexed 0..n-1 in the order of ``priors.candidate_categories``.

    Attributes
    ----------
    priors : Priors
        What the engine answers from.
    options : EngineOptions
        Its weights and switches.
    candidates : ndarray of shape (n,), int
        The priors' category index of each candidate.
    names : list of str, length n
        Each candidate's category; ``index`` maps a category back to its candidate.
    name_order : ndarray of shape (n,), int
        Each candidate's rank by name (ties in score are broken by name).
    stat_entity : ndarray of shape (n,), int64
        The priors' entity whose statistics each candidate uses after taxonomy back-off.
    members : list of tuple of str, length n
        Each candidate's models, the most used first (the first is its representative).
    size : ndarray of shape (n, 3), float
        The representative model's bounding-box size (metres, its canonical frame).
    surface_prob : ndarray of shape (n, surface types)
        P_sup(t | C), with the geometric fallback where a category was never seen supported.
    face_prob : ndarray of shape (n, surface types, faces)
        P_att(f | C, t); rows of zeros where never observed.
    geometric_faces : dict of str to ndarray of shape (n,), int
        Per surface normal (up, down, vertical): the attachment face the bounding box suggests.
    share : ndarray of shape (n,)
        A backed-off candidate's share of its ancestor's occurrences (1 where it has its own statistics).
    base_rate : ndarray of shape (n,)
        How often each candidate rests on anything at all (for a parent never seen).
    weights : ndarray of shape (n, surface types, evidence kinds), float
        The learned orientation evidence weights (:mod:`scenesuggest.learning.orientation`).
    """

    name = "paper"

    def __init__(self, priors: Priors, options: EngineOptions | None = None):
        self.priors = priors
        self.options = options or EngineOptions()
        p = priors
        self.candidates = p.candidate_categories
        self.names = [p.categories[c] for c in self.candidates]
        self.index = {name: i for i, name in enumerate(self.names)}
        self.suggestable = suggestable_mask(self.names)  # placeholders (Room, Unknown) score but are never ranked
        self.name_order = np.argsort(np.argsort(self.names))  # ties are broken by name
        n = len(self.candidates)
        self.stat_entity = np.array([self._stat_entity(name) for name in self.names], dtype=np.int64)
        members = {i: [] for i in range(n)}
        cand_pos = {int(c): i for i, c in enumerate(self.candidates)}
        for m, c in enumerate(p.model_category):
            members[cand_pos[int(c)]].append(m)
        self.members = [tuple(p.model_ids[m] for m in sorted(ms, key=lambda m: -p.model_count[m])) for
                        _, ms in sorted(members.items())]
        self.size = np.array([p.model_size[max(ms, key=lambda m: p.model_count[m])] for _, ms in
                              sorted(members.items())], dtype=float)
        self.surface_prob = np.array([self._surface_prob(name) for name in self.names])  # (n, 6)
        self.face_prob = np.array([self._face_prob(name) for name in self.names])  # (n, 6, 6)
        self.geometric_faces = {d: np.array([FACES.index(self.geometric_face(size, f"{d}_interior"))
                                             for size in self.size]) for d in ("up", "down", "vertical")}
        total = p.occ_parent_n[: len(p.categories), -1].sum()
        own = p.sup_counts[self.candidates].sum(axis=1)  # exact entities share the category indices
        pooled = p.sup_counts[self.stat_entity].sum(axis=1)
        # a category backed off to an ancestor's subtree gets its share of that subtree's occurrences
        self.share = np.where(pooled > 0, own / np.maximum(pooled, 1.0), 1.0)
        self.base_rate = own / max(total, 1.0)
        self.weights = p.orient_weights[self.candidates].astype(float)  # (n, surface types, kinds)
        self._cache: dict[tuple, Resolution] = {}
        self._segments: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self._categories: dict[str, tuple[str, ...]] | None = None

    @property
    def categories(self) -> dict[str, tuple[str, ...]]:
        """Every category the engine can suggest (no placeholder) → its models, the most used first."""
        if self._categories is None:
            self._categories = {name: members for name, members, ok in
                                zip(self.names, self.members, self.suggestable, strict=True) if ok}
        return self._categories

    # --- per-category statistics after back-off -------------------------------------------------------------
    def _stat_entity(self, category: str) -> int:
        return self.priors.stat_entity(category, self.options.backoff)

    def _surface_prob(self, category: str) -> np.ndarray:
        counts = self.priors.sup_counts[self._stat_entity(category)].astype(float)
        if counts.sum() == 0:  # geometric fallback: upward surfaces support
            counts = np.array([4.0 if t.startswith("up") else 0.25 for t in SURFACE_TYPES])
        return counts / counts.sum()

    def _face_prob(self, category: str) -> np.ndarray:
        """P_att(f | C, t) for every surface type (rows of zeros where never observed)."""
        counts = self.priors.att_counts[self._stat_entity(category)].astype(float)
        totals = counts.sum(axis=1, keepdims=True)
        return np.divide(counts, totals, out=np.zeros_like(counts), where=totals > 0)

    # --- queries -------------------------------------------------------------------------------------------
    def prepare(self, query: ContextQuery) -> Prepared:
        """Validate a query (errors name the field) and derive surface type, scene type and references."""
        return prepare(query, self.priors.taxonomy, self.options.infer_scene_type)

    def score(self, query: ContextQuery, allowed: np.ndarray | None = None) -> Scores:
        """Every candidate's terms and score for ``query``; ``allowed`` (a mask over the candidates: those that
        may be suggested) lets an engine spend its effort on them — this one scores all alike."""
        return self._score(query)

    def _score(self, query: ContextQuery) -> Scores:
        prep = self.prepare(query)
        occ = self._occurrence(prep)
        sup = self.surface_prob[:, SURFACE_TYPES.index(prep.surface_type)]
        densities = self._reference_densities(prep)
        position = np.sum(densities, axis=0) if densities else np.zeros(len(self.candidates))
        o = self.options
        total = o.lambda1 * occ * sup + o.lambda2 * position
        return Scores(prep, occ, sup, position, total, densities)

    def _occurrence(self, prep: Prepared) -> np.ndarray:
        p = self.priors
        dense = p.occurrence_table(prep.parent_category, prep.scene_type, self.options.backoff)
        if dense is None:  # an unseen parent: how often each category rests on anything at all
            return self.base_rate * p.borrowed(self.stat_entity, len(p.scene_types) - 1, prep.scene_type)
        k = np.zeros(len(p.entities), dtype=int)
        for child in prep.query.scene.children(prep.query.parent_id):
            k[self.priors.entity_chain(child.category)] += 1
        return dense[self.stat_entity, np.minimum(k[self.stat_entity], K_MAX)] * self.share

    def pair_sources(self, ref_category: str, scene_type: str, relation: str, surface_type: str
                     ) -> tuple[np.ndarray, np.ndarray]:
        """One reference key's (candidates,) pair segments of the priors (−1 where a candidate has none) and their
        back-off trust (:meth:`Priors.pair_sources`), memoised: what the heading evidence reads."""
        key = (ref_category, scene_type, relation, surface_type)
        hit = self._segments.get(key)
        if hit is None:
            hit = self._segments[key] = self.priors.pair_sources(self.stat_entity, ref_category, scene_type,
                                                                 relation, surface_type, self.options.backoff)
        return hit

    def resolve(self, ref_category: str, scene_type: str, relation: str, surface_type: str) -> Resolution:
        """One reference key resolved for every candidate: the KDE samples of their relative positions and their
        pair segments (memoised; pure)."""
        key = (ref_category, scene_type, relation, surface_type)
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        p = self.priors
        seg, trust = self.pair_sources(*key)
        has = np.flatnonzero(seg >= 0)
        starts, counts = p.seg_start[seg[has]], p.seg_count[seg[has]]
        owner = np.repeat(has, counts)
        segs_rep = np.repeat(seg[has], counts)
        sample = np.repeat(starts - np.r_[0, np.cumsum(counts)[:-1]], counts) + np.arange(counts.sum())
        value = Resolution(p.sample_xy[sample], p.seg_inv_bandwidth[segs_rep], p.seg_weight64[segs_rep] * trust[owner],
                           owner, seg)
        self._cache[key] = value
        return value

    def _reference_densities(self, prep: Prepared, point: np.ndarray | None = None) -> list[np.ndarray]:
        """For every reference: each candidate's P_relpos at ``point`` (default: the query's), scaled by the
        category's back-off share — one kernel sum over every reference's samples."""
        refs = prep.references
        n = len(self.candidates)
        if not refs:
            return []
        resolved = [self.resolve(ref.category, prep.scene_type, relation, prep.surface_type)
                    for ref, relation in refs]
        delta = poses.plane_offsets(prep.point if point is None else point, prep.normal,
                                    np.array([ref.transform for ref, _ in refs]),
                                    is_radial(np.array([ref.size for ref, _ in refs], dtype=float)))
        sizes = [len(r.owner) for r in resolved]
        if not sum(sizes):
            return [np.zeros(n) for _ in refs]
        which = np.repeat(np.arange(len(refs)), sizes)
        xy = np.concatenate([r.xy for r in resolved])
        inv_bw = np.concatenate([r.inv_bandwidth for r in resolved])
        weight = np.concatenate([r.weight for r in resolved])
        owner = np.concatenate([r.owner for r in resolved])
        scaled = (delta[which] - xy) * inv_bw
        scaled *= scaled
        q = scaled[:, 0] + scaled[:, 1]  # the squared scaled distance (a sum over a 2-wide axis is slower)
        out = np.bincount(which * n + owner, weights=weight * np.exp(-0.5 * q), minlength=len(refs) * n)
        return list(out.reshape(len(refs), n) * self.share)

    def position_at(self, prep: Prepared, points: np.ndarray) -> np.ndarray:
        """(P, n) position term Σ_r P_relpos of every candidate at each of ``points``."""
        n = len(self.candidates)
        return np.array([np.sum(self._reference_densities(prep, point), axis=0) if prep.references
                         else np.zeros(n) for point in points]).reshape(len(points), n)

    # --- orientation ---------------------------------------------------------------------------------------
    def heading_scores(self, scores: Scores, idx: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(m, BINS) score of each heading bin for candidates ``idx`` attached by ``faces`` (indices into
        FACES): the learned log-score, or the paper's Σ_r P_relpos · P_relori (by the orientation option)."""
        if self.options.orientation == "paper":
            return headings.paper_scores(self, scores, idx)
        return headings.learned_scores(self, scores.prepared, idx, faces)

    # --- placement -----------------------------------------------------------------------------------------
    def geometric_face(self, size, surface_type: str) -> str:
        """Attachment by geometry: hang by the top from ceilings, stand on the bottom on floors and tops,
        and on walls attach along the thinnest horizontal axis (flat things by their back, thin by a side)."""
        direction = surface_type.split("_")[0]
        if direction == "down":
            return "top"
        if direction == "up":
            return "bottom"
        sx, sy, sz = size
        return "back" if sz <= sx or sz <= 0.5 * sy else "right"

    def face_indices(self, prep: Prepared, mode: str, idx: np.ndarray) -> np.ndarray:
        """Attachment face (index into FACES) of candidates ``idx``: by geometry in ``basic``; in ``full`` the
        most frequent face on this surface type (by geometry where none was observed)."""
        geometric = self.geometric_faces[prep.surface_type.split("_")[0]][idx]
        if mode != "full":
            return geometric
        t = SURFACE_TYPES.index(prep.surface_type)
        prob = self.face_prob[idx, t]
        return np.where(prob.sum(axis=1) > 0, np.argmax(prob, axis=1), geometric)

    def choose_poses(self, scores: Scores, mode: str, idx: np.ndarray | None = None
                     ) -> tuple[list[str], np.ndarray, np.ndarray]:
        """(face, α, heading) of candidates ``idx`` (default: all) in ``mode`` (see the module docstring)."""
        prep = scores.prepared
        idx = np.arange(len(self.candidates)) if idx is None else np.asarray(idx, dtype=np.int64)
        face_index = self.face_indices(prep, mode, idx)
        zero = poses.zero_headings(prep.normal)[face_index]
        if mode != "full":
            heading = zero
        elif self.options.orientation == "paper":
            score = self.heading_scores(scores, idx, face_index)
            heading = np.where(score.max(axis=1) > 0, HEADINGS[np.argmax(score, axis=1)], zero)
        else:
            heading, _ = decide(self.heading_scores(scores, idx, face_index), zero)
        return [FACES[i] for i in face_index], heading - zero, heading

    def suggest(self, query: ContextQuery, mode: str = "full", top: int | None = None,
                only: Collection[str] | None = None) -> SuggestionList:
        """Ranked suggestions (best first, ties by name), each with a placement; ``top`` limits the list and
        ``only`` (category names) the categories that may appear, as a study whose library lacks some does; a
        placeholder category never does (:mod:`.suggestable`)."""
        if mode not in MODES:
            raise SceneSuggestError(f"mode must be one of {', '.join(MODES)} (the 'none' condition never asks "
                                    "the engine)", field="mode")
        if top is not None and (not isinstance(top, int) or top < 1):
            raise SceneSuggestError("top must be a positive integer", field="top")
        n = len(self.candidates)
        allowed = self.suggestable if only is None else self.suggestable & np.isin(self.names, list(only))
        scores = self.score(query, allowed)
        prep = scores.prepared
        points = np.broadcast_to(prep.point, (n, 3))
        notes: list[list[str]] | None = None  # said of a candidate only when an extra changed it
        total = scores.total
        if self.options.anchor_refinement or self.options.collision_aware:
            notes = [[] for _ in range(n)]
        if self.options.anchor_refinement:
            points, moved = refine_anchors(self, scores, self.options.refine_radius_m)
            for i in np.flatnonzero(moved > 0):
                notes[i].append(f"moved {moved[i]:.2f} m to a more typical spot")
        if not allowed.any():  # nothing the caller allows
            return SuggestionList((), prep.surface_type, prep.scene_type, prep.parent_category, self.name)
        if self.options.collision_aware:  # every candidate needs its pose before the ranking is known
            faces, alphas, headings = self.choose_poses(scores, mode)
            total, alphas, headings, notes = check_fit(self, scores, faces, alphas, headings, points, total, notes,
                                                       mode)
            order = self._ranking(total, allowed)[: top or n]
            faces, alphas, headings = [faces[i] for i in order], alphas[order], headings[order]
        else:
            order = self._ranking(total, allowed)[: top or n]
            faces, alphas, headings = self.choose_poses(scores, mode, order)
        placed = poses.placements(points[order], prep.normal, faces, self.size[order], alphas)
        degrees = np.degrees(poses.wrap(headings)).tolist()
        out = []
        for rank, (i, placement, terms, score) in enumerate(zip(
                order.tolist(), placed, self.term_rows(scores, order), total[order].tolist(), strict=True), start=1):
            out.append(Suggestion(
                rank=rank, category=self.names[i], score=score, terms=terms,
                placement=placement, attachment_face=faces[rank - 1], heading_deg=degrees[rank - 1],
                models=self.members[i], notes=tuple(notes[i]) if notes is not None else ()))
        return SuggestionList(tuple(out), prep.surface_type, prep.scene_type, prep.parent_category, self.name)

    def explain(self, query: ContextQuery, mode: str = "full", top: int | None = 10,
                categories: Collection[str] = ()) -> list[dict]:
        """Why each category got its rank among every category that may be suggested (whatever the study allows;
        the extras of EngineOptions are not applied), for the ``top`` suggestions and ``categories`` wherever they
        rank: its score and the contributions that sum to it — λ1 · occurrence · surface, then λ2 · the position
        density next to each reference (the parent and the objects on it)."""
        scores = self.score(query)
        rank, wanted = self.explained(scores, top, categories)
        o = self.options
        out = []
        for i in wanted:
            parts = [{"feature": "occurrence × surface", "value": float(scores.occurrence[i] * scores.surface[i]),
                      "contribution": float(o.lambda1 * scores.occurrence[i] * scores.surface[i])}]
            for (ref, relation), density in zip(scores.prepared.references, scores.densities, strict=True):
                parts.append({"feature": f"position by the {relation} {ref.category} {ref.id!r}",
                              "value": float(density[i]), "contribution": float(o.lambda2 * density[i])})
            parts.sort(key=lambda p: -abs(p["contribution"]))
            out.append({"rank": rank[i], "category": self.names[i], "score": float(scores.total[i]), "baseline": 0.0,
                        "terms": self.terms(scores, i), "contributions": parts})
        return out

    def explained(self, scores: Scores, top: int | None, categories: Collection[str]) -> tuple[dict, list[int]]:
        """(candidate → its rank among every candidate that may be suggested, the candidates to explain: the
        ``top`` and ``categories`` wherever they rank) — what every engine's ``explain`` lists."""
        order = self._ranking(scores.total, self.suggestable)
        rank = {int(i): r for r, i in enumerate(order, start=1)}
        wanted = [int(i) for i in order[: top or len(order)]] + [self.index[c] for c in categories
                                                                 if c in self.index and suggestable(c)]
        return rank, list(dict.fromkeys(wanted))

    def term_columns(self, scores: Scores) -> dict[str, np.ndarray]:
        """The explanation terms of every candidate, by name: the paper's occurrence, surface and position terms."""
        return {"occurrence": scores.occurrence, "surface": scores.surface, "position": scores.position}

    def terms(self, scores: Scores, i: int) -> dict[str, float]:
        """The explanation terms of candidate ``i`` (:meth:`term_columns`)."""
        return self.term_rows(scores, [i])[0]

    def term_rows(self, scores: Scores, idx) -> list[dict[str, float]]:
        """The explanation terms of candidates ``idx``, one dict each (:meth:`term_columns`, read once)."""
        columns = {name: np.asarray(values, dtype=float)[idx].tolist()
                   for name, values in self.term_columns(scores).items()}
        return [dict(zip(columns, row, strict=True)) for row in zip(*columns.values(), strict=True)]

    def _ranking(self, total: np.ndarray, allowed: np.ndarray) -> np.ndarray:
        """Candidate indices best first (ties by name), only the allowed ones."""
        order = np.lexsort((self.name_order, -total))
        return order[allowed[order]]

    def with_options(self, **changes) -> Engine:
        return type(self)(self.priors, replace(self.options, **changes))


__all__ = ["ANY", "ContextQuery", "Engine", "EngineOptions", "MODES", "ORIENTATIONS", "Suggestion"]
