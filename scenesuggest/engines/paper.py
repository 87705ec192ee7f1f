"""The ``paper`` engine: the paper's factors (:class:`scenesuggest.suggestion.suggest.Engine`) answering from a priors
file, with its options (:class:`~scenesuggest.suggestion.suggest.EngineOptions`: the weights λ1, λ2, back-off, the
orientation rule and the extras beyond the paper). What the replication runs, and the default of every condition."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any

from ..errors import SceneSuggestError
from ..learning.priors import Priors
from ..suggestion.suggest import Engine, EngineOptions
from .protocol import EngineKind, LoadContext

#: The options a study condition may give the paper's engine (the fields of EngineOptions).
OPTIONS = tuple(f.name for f in fields(EngineOptions))


def engine_options(options: Mapping[str, Any], allowed: tuple[str, ...] = OPTIONS) -> EngineOptions:
    """:class:`EngineOptions` from a table; an unknown key or a bad value is an error naming the key."""
    for key in options:
        if key not in allowed:
            raise SceneSuggestError(f"unknown key: this engine takes name, {', '.join(allowed)}", field=key)
    for key, value in options.items():
        default = getattr(EngineOptions, key)
        if isinstance(default, bool) and not isinstance(value, bool):
            raise SceneSuggestError("expected true or false", field=key)
        if isinstance(default, float) and (isinstance(value, bool) or not isinstance(value, int | float)):
            raise SceneSuggestError("expected a number", field=key)
    return EngineOptions(**options)


class PaperKind(EngineKind):
    name = "paper"
    version = "1"
    summary = "the paper's factors: occurrence × support surface + λ2 · relative position; oriented in full mode"
    trainable = True

    def configure(self, options: Mapping[str, Any], base: Path | None = None) -> EngineOptions:
        return engine_options(options)

    def load(self, config: EngineOptions, context: LoadContext) -> Engine:
        return Engine(Priors.load(context.priors), config)

    def from_priors(self, config: EngineOptions, priors: Priors) -> Engine:
        """The engine answering from priors already learned (what ``evaluate`` trains once per fold)."""
        return Engine(priors, config)

    def fit(self, config: EngineOptions, scenes, taxonomy, *, seed: int = 0, progress=None, periods=None) -> Engine:
        return Engine(Priors.fit(scenes, taxonomy, progress=progress), config)

    def train(self, config: EngineOptions, scenes, taxonomy, out: Path, *, seed: int = 0, progress=None,
              periods=None) -> dict:
        priors = Priors.fit(scenes, taxonomy, progress=progress)
        path = priors.save(out)
        return {"out": str(path), "bytes": path.stat().st_size, **priors.describe()}


KIND = PaperKind()
