"""The ``frequency`` engine: every category ranked by how often it occurs in the corpus (its share of supported
instances), whatever was clicked — a control condition for a study, and the evaluation's ``frequency`` baseline.
It reads the study's priors file and places each category as the paper's engine does (``basic``: canonical pose;
``full``: oriented by the priors)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..learning.priors import Priors
from ..suggestion.suggest import Engine, EngineOptions, Scores
from .paper import engine_options
from .protocol import EngineKind, LoadContext

#: Options: how ``full`` mode orients (the placement is the paper engine's).
OPTIONS = ("orientation",)


class FrequencyEngine(Engine):
    """Scores every category by its base rate (supported instances of it / all supported instances)."""

    name = "frequency"

    def score(self, query, allowed=None) -> Scores:
        """The base rate of every candidate (the paper's terms are not computed: only the paper's orientation
        rule needs its position densities)."""
        prep = self.prepare(query)
        n = len(self.candidates)
        densities = self._reference_densities(prep) if self.options.orientation == "paper" else []
        zeros = np.zeros(n)
        return Scores(prep, zeros, np.ones(n), zeros, self.base_rate.copy(), densities)

    def term_columns(self, scores: Scores) -> dict[str, np.ndarray]:
        return {"frequency": self.base_rate}

    def explain(self, query, mode: str = "full", top: int | None = 10, categories=()) -> list[dict]:
        scores = self.score(query)
        rank, wanted = self.explained(scores, top, categories)
        return [{"rank": rank[i], "category": self.names[i], "score": float(self.base_rate[i]), "baseline": 0.0,
                 "terms": self.terms(scores, i), "contributions": [
                     {"feature": "frequency", "value": float(self.base_rate[i]),
                      "contribution": float(self.base_rate[i])}]} for i in wanted]


class FrequencyKind(EngineKind):
    name = "frequency"
    version = "1"
    summary = "categories by how often they occur in the corpus, whatever was clicked (a control)"
    trainable = True

    def configure(self, options: Mapping[str, Any], base: Path | None = None) -> EngineOptions:
        return engine_options(options, OPTIONS)

    def load(self, config: EngineOptions, context: LoadContext) -> FrequencyEngine:
        return FrequencyEngine(Priors.load(context.priors), config)

    def from_priors(self, config: EngineOptions, priors: Priors) -> FrequencyEngine:
        return FrequencyEngine(priors, config)

    def fit(self, config: EngineOptions, scenes, taxonomy, *, seed: int = 0, progress=None,
            periods=None) -> FrequencyEngine:
        return FrequencyEngine(Priors.fit(scenes, taxonomy, progress=progress), config)

    def train(self, config, scenes, taxonomy, out: Path, *, seed: int = 0, progress=None, periods=None) -> dict:
        from .paper import KIND as PAPER

        return PAPER.train(config, scenes, taxonomy, out, seed=seed, progress=progress)


KIND = FrequencyKind()
