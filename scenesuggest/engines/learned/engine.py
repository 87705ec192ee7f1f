"""The learned engine at query time, and its file.

A click is scored by the paper's engine (the priors in the file), its context counted (:mod:`.context`), and
every candidate's ranking row (:func:`.features.ranking_features`) scored by the ranker, a LightGBM lambdarank
model: the higher, the better. Headings are the paper engine's (in ``full`` mode the product of the orientation
evidence, ``basic`` the canonical pose); with ``frames`` (a study condition's ``frames = true``) each suggestion in
``full`` mode gets instead the heading of the reference frame the frame classifier trusts most for it
(:func:`.features.frame_proposals`). Held out, the classifier gains half a point to a point of orientation for about
1.6 ms of a query's p95 (ENGINE.md), so it is asked only when chosen. Attachment faces and placements are the paper
engine's.

The file is one ``.npz`` (written by :mod:`scenesuggest.npz`, so the same training gives the same bytes): the
priors' arrays and metadata under ``priors.``, the context counts under ``context.``, the two models as text
(``ranker``, ``frames``) and ``meta`` (JSON: format, version, the feature and frame names, the training's seed
and size).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import lightgbm as lgb
import numpy as np

from ...atomic import write_atomically
from ...digest import ENGINE_SOURCES, source_digest
from ...errors import SceneSuggestError
from ...learning.priors import Priors
from ...npz import npz_bytes, read_npz
from ...scenes import poses
from ...scenes.frames import FACES
from ...suggestion.suggest import Engine, EngineOptions, Scores
from .context import ContextStats
from .features import FRAMES, ORIENTATION, RANKING, frame_proposals, ranking_features
from .model_text import check_model_text

FORMAT = "scenesuggest-learned"
VERSION = 1
#: Contributions of the ranker's features listed per suggestion by :meth:`LearnedEngine.explain`.
EXPLAIN_TOP = 6
#: The ranker's first SHORTLIST_TREES trees pick the SHORTLIST candidates that all its trees then rank; the others
#: follow in the order of the first trees' score. On grouped 5-fold Stanford this changed no rank that matters
#: (MRR 0.3392 with and without) and cut the ranker's time by half.
SHORTLIST_TREES = 30
SHORTLIST = 80


def code_digest() -> str:
    """A short hash of the code that decides what a learned engine's file holds (the priors' code and this
    package's): files the server prepared for itself are trained again when it changes."""
    return source_digest(*ENGINE_SOURCES, "engines/learned/*.py")


def _text(array: np.ndarray) -> str:
    return array.tobytes().decode()


def _bytes(text: str) -> np.ndarray:
    return np.frombuffer(text.encode(), dtype=np.uint8)


class LearnedEngine(Engine):
    """Answers context queries with the learned ranker and frame classifier (see the module docstring).

    Attributes
    ----------
    priors : Priors
        The paper's priors, trained on the same scenes as the models (the paper's terms are features).
    stats : ContextStats
        Context counts over the candidate categories.
    ranker : lightgbm.Booster
        Scores ranking rows (columns in the order of ``features.RANKING``).
    frames : lightgbm.Booster or None
        Probability that a frame's heading is within 45° of the truth (rows in the order of
        ``features.ORIENTATION``); None: the product of the evidence (the paper engine's ``full``).
    meta : dict
        The file's metadata.
    choose_frames : bool
        Whether ``full`` mode turns each suggestion as the frame classifier chooses (else as the paper's engine).
    """

    name = "learned"

    def __init__(self, priors: Priors, stats: ContextStats, ranker: lgb.Booster, frames: lgb.Booster | None,
                 meta: dict, options: EngineOptions | None = None, choose_frames: bool = False):
        super().__init__(priors, options)
        if list(stats.names) != list(self.names):
            raise SceneSuggestError("the context counts and the priors name different categories", field="context")
        self.stats, self.ranker, self.frames, self.meta = stats, ranker, frames, meta
        self.choose_frames = choose_frames

    # --- ranking -------------------------------------------------------------------------------------------
    def score(self, query, allowed: np.ndarray | None = None) -> Scores:
        """The paper's terms of every candidate, with ``total`` the ranker's score and ``features`` its rows; the
        shortlist (SHORTLIST) is drawn from the ``allowed`` candidates (default: all)."""
        scores = self._score(query)
        scores.features = ranking_features(self, self.stats, scores)
        scores.paper_total = scores.total
        scores.total = self._rank(scores.features, allowed)
        return scores

    def _shortlist(self, rows: np.ndarray, allowed: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray] | None:
        """(the first trees' score of every row, the shortlisted rows — the best of the ``allowed`` ones), None
        when every row is ranked whole."""
        if len(rows) <= SHORTLIST or self.ranker.num_trees() <= SHORTLIST_TREES:
            return None
        first = self.ranker.predict(rows, num_iteration=SHORTLIST_TREES, num_threads=1)
        keys = first if allowed is None else np.where(allowed, first, -np.inf)
        return first, np.argpartition(-keys, SHORTLIST)[:SHORTLIST]

    def _rank(self, rows: np.ndarray, allowed: np.ndarray | None = None) -> np.ndarray:
        """The ranker's score of every row: all its trees for the shortlist (see SHORTLIST), and below every
        shortlisted score, in their order, the first trees' score for the rest."""
        found = self._shortlist(rows, allowed)
        if found is None:
            return self.ranker.predict(rows, num_threads=1)
        first, short = found
        full = first[short] + self.ranker.predict(rows[short], start_iteration=SHORTLIST_TREES, num_threads=1)
        rest = np.ones(len(rows), dtype=bool)
        rest[short] = False
        total = first - (first[rest].max() - full.min()) - 1.0
        total[short] = full
        return total

    def term_columns(self, scores: Scores) -> dict[str, np.ndarray]:
        return {**super().term_columns(scores), "paper_score": scores.paper_total, "learned_score": scores.total}

    # --- orientation ---------------------------------------------------------------------------------------
    def choose_poses(self, scores: Scores, mode: str, idx: np.ndarray | None = None
                     ) -> tuple[list[str], np.ndarray, np.ndarray]:
        """(face, α, heading) of candidates ``idx``: the paper engine's, or with ``choose_frames`` in ``full``
        mode :meth:`frame_poses`."""
        if mode != "full" or self.frames is None or not self.choose_frames:
            return super().choose_poses(scores, mode, idx)
        return self.frame_poses(scores, idx)

    def frame_poses(self, scores: Scores, idx: np.ndarray | None = None) -> tuple[list[str], np.ndarray, np.ndarray]:
        """(face, α, heading) of candidates ``idx`` in ``full`` mode with the heading of the frame the classifier
        trusts most for each (the product of the evidence when there is no classifier), whatever ``choose_frames``
        says."""
        idx = np.arange(len(self.candidates)) if idx is None else np.asarray(idx, dtype=np.int64)
        face_index = self.face_indices(scores.prepared, "full", idx)
        zero = poses.zero_headings(scores.prepared.normal)[face_index]
        heading = self.frame_headings(scores, idx, face_index)[1]
        return [FACES[i] for i in face_index], heading - zero, heading

    def frame_headings(self, scores: Scores, idx: np.ndarray, face_index: np.ndarray | None = None
                       ) -> tuple[list[str], np.ndarray, np.ndarray]:
        """(the frame chosen for each of candidates ``idx``, its heading (radians), every frame's heading
        (len(idx), len(FRAMES))); where every frame proposes the same heading, the first (``product``) is chosen
        without asking the classifier."""
        idx = np.asarray(idx, dtype=np.int64)
        face_index = self.face_indices(scores.prepared, "full", idx) if face_index is None else face_index
        proposed, rows = frame_proposals(self, scores, idx, face_index)
        # where every frame proposes one heading, any choice gives it: the classifier is asked about the others
        asked = np.flatnonzero((proposed != proposed[:, :1]).any(axis=1))
        trust = np.zeros((len(idx), len(FRAMES)))  # without a classifier: the product of the evidence
        if len(asked) and self.frames is not None:
            trust[asked] = self.frames.predict(rows[asked].reshape(-1, rows.shape[-1]),
                                               num_threads=1).reshape(len(asked), len(FRAMES))
        best = np.argmax(trust, axis=1)
        return [FRAMES[k] for k in best], proposed[np.arange(len(idx)), best], proposed

    # --- explanation ---------------------------------------------------------------------------------------
    def explain(self, query, mode: str = "full", top: int | None = 10, categories=()) -> list[dict]:
        """Why each category got its rank among every category that may be suggested (whatever the study allows):
        the ranker's score, and the largest
        contributions of its features (SHAP values, in the ranker's score units) with the features' values; for the
        ``top`` suggestions and for ``categories`` wherever they rank. A category the first trees left out of the
        shortlist is explained by those trees, and its place below the shortlist is one more contribution
        (``below the shortlist``), so that the contributions and the baseline always sum to the score."""
        scores = self.score(query, self.suggestable)  # shortlisted as suggest does when the study allows all
        rank, wanted = self.explained(scores, top, categories)
        found = self._shortlist(scores.features, self.suggestable)
        short = set(range(len(self.candidates))) if found is None else set(found[1].tolist())
        out = []
        for i in wanted:
            iterations = None if i in short else SHORTLIST_TREES
            row = self.ranker.predict(scores.features[[i]], pred_contrib=True, num_iteration=iterations,
                                      num_threads=1)[0]
            largest = np.argsort(-np.abs(row[:-1]), kind="stable")[:EXPLAIN_TOP]
            parts = [{"feature": RANKING[k], "value": float(scores.features[i, k]), "contribution": float(row[k])}
                     for k in largest]
            rest = float(row[:-1].sum() - sum(p["contribution"] for p in parts))
            parts.append({"feature": f"the other {len(RANKING) - len(largest)} features", "value": None,
                          "contribution": rest})
            if i not in short:
                parts.append({"feature": "below the shortlist", "value": None,
                              "contribution": float(scores.total[i] - row.sum())})
            out.append({"rank": rank[i], "category": self.names[i], "score": float(scores.total[i]),
                        "baseline": float(row[-1]), "shortlisted": i in short, "terms": self.terms(scores, i),
                        "contributions": parts})
        return out

    def with_options(self, **changes) -> LearnedEngine:
        return LearnedEngine(self.priors, self.stats, self.ranker, self.frames, self.meta,
                             replace(self.options, **changes), self.choose_frames)

    def choosing_frames(self, choose: bool) -> LearnedEngine:
        """This engine, turning suggestions as its frame classifier chooses (``choose``) or as the paper's; asking
        for a classifier the file lacks (its corpus gave it nothing to choose between) is an error."""
        if choose == self.choose_frames:
            return self
        if choose and self.frames is None:
            raise SceneSuggestError("this learned engine has no frame classifier (its training scenes gave it no "
                                    "choice of frames to learn): leave out frames = true", field="frames")
        return LearnedEngine(self.priors, self.stats, self.ranker, self.frames, self.meta, self.options, choose)

    # --- the file ------------------------------------------------------------------------------------------
    def payload(self) -> dict[str, np.ndarray]:
        out = {f"priors.{k}": v for k, v in self.priors.payload().items()}
        out.update({f"context.{k}": v for k, v in self.stats.arrays.items()})
        out["ranker"] = _bytes(self.ranker.model_to_string())
        if self.frames is not None:
            out["frames"] = _bytes(self.frames.model_to_string())
        meta = {"code": code_digest(), **self.meta, "format": FORMAT, "version": VERSION,
                "ranking_features": list(RANKING),
                "frames": list(FRAMES), "orientation_features": list(ORIENTATION),
                "context": {"names": self.stats.names, "scene_types": self.stats.scene_types}}
        out["meta"] = _bytes(json.dumps(meta, sort_keys=True))
        return out

    def save(self, path: str | Path) -> Path:
        """Write the engine's file, whole or not at all; the same engine gives the same bytes."""
        return write_atomically(path, npz_bytes(self.payload()))

    @staticmethod
    def read_meta(path: str | Path) -> dict:
        """The metadata of a learned engine's file, checked as :meth:`load` checks it, without reading the rest."""
        path = Path(path)
        return _checked_meta(read_npz(path, ("meta",), "the learned engine").get("meta"), path)

    @classmethod
    def load(cls, path: str | Path, options: EngineOptions | None = None, choose_frames: bool = False
             ) -> LearnedEngine:
        """Read a learned engine's file; one that is not one, or of another version, is an error naming it."""
        path = Path(path)
        payload = read_npz(path, what="the learned engine")
        meta = _checked_meta(payload.get("meta"), path)
        try:
            priors = Priors.from_payload({k[7:]: v for k, v in payload.items() if k.startswith("priors.")}, path)
            context = meta["context"]
            stats = ContextStats(context["names"], context["scene_types"],
                                 {k[8:]: v for k, v in payload.items() if k.startswith("context.")})
            ranker = _booster(payload["ranker"], len(RANKING), "ranker", path)
            frames = _booster(payload["frames"], len(ORIENTATION), "frames", path) if "frames" in payload else None
        except (KeyError, TypeError, lgb.basic.LightGBMError, UnicodeDecodeError) as e:
            raise SceneSuggestError(f"the learned engine's file is incomplete or damaged ({type(e).__name__}: {e})",
                                    file=str(path), field="ranker") from None
        return cls(priors, stats, ranker, frames, meta, options).choosing_frames(choose_frames)


def _booster(raw: np.ndarray, features: int, name: str, path: Path) -> lgb.Booster:
    """One of the file's LightGBM models, its text checked first (:mod:`.model_text`): LightGBM aborts the process
    on some damaged texts instead of raising."""
    text = _text(raw)
    try:
        check_model_text(text, features)
    except ValueError as e:
        raise SceneSuggestError(f"the learned engine's {name} model is damaged: {e}", file=str(path),
                                field=name) from None
    return lgb.Booster(model_str=text)


def _checked_meta(raw: np.ndarray | None, path: Path) -> dict:
    """The file's metadata: present, JSON, this format and this version of the features."""
    try:
        meta = json.loads(_text(raw)) if raw is not None else None
    except (UnicodeDecodeError, ValueError):
        meta = None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise SceneSuggestError("not a learned engine's file", file=str(path), field="format")
    if (meta.get("version") != VERSION or meta.get("ranking_features") != list(RANKING)
            or meta.get("orientation_features") != list(ORIENTATION)):
        raise SceneSuggestError(f"a learned engine of another version ({meta.get('version')!r}): train it again "
                                "with 'scenesuggest engine train learned'", file=str(path), field="version")
    return meta
