"""What an engine is: a query in, a :class:`~scenesuggest.suggestion.suggest.SuggestionList` out — and how a kind of
engine is configured, trained and loaded.

The query (:class:`~scenesuggest.suggestion.query.ContextQuery`) is a click: the scene (world frame, metres, +Y up), the
clicked parent's id, the world point and the surface normal there, optionally the scene type; with it, the mode
(``basic``: canonical pose; ``full``: oriented), how many suggestions to return (``top``) and which categories
may appear (``only``: those the study's library can place). The answer ranks categories best first; each carries
its score, its placement (a 4×4 canonical → world transform), attachment face, heading (degrees about the
surface normal), the category's models (a representative first) and its explanation ``terms`` (the paper's
occurrence, surface and position terms; a learned engine's largest feature contributions).

A *kind* of engine (:class:`EngineKind`) is what a registry name stands for (:mod:`scenesuggest.engines`):
it validates a study condition's options (:meth:`EngineKind.configure`, errors name the option), names the
file its answers come from (:meth:`EngineKind.trained_file`, whose SHA-256 an export records), loads an engine
from it (:meth:`EngineKind.load`), and, when the project can train it, fits one on scenes
(:meth:`EngineKind.fit`, what ``evaluate`` does per fold) or trains its file (:meth:`EngineKind.train`).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from ..corpora.corpus import Progress
from ..scenes.scene import Scene
from ..scenes.taxonomy import Taxonomy
from ..suggestion.query import ContextQuery
from ..suggestion.suggest import SuggestionList


@runtime_checkable
class SuggestionEngine(Protocol):
    """An engine that answers context queries. ``name`` is its registry name; ``categories`` maps every
    category it can suggest to its models (a representative first)."""

    name: str
    categories: Mapping[str, tuple[str, ...]]

    def suggest(self, query: ContextQuery, mode: str = "full", top: int | None = None,
                only: Collection[str] | None = None) -> SuggestionList:
        """Ranked, placed suggestions for ``query`` (see the module docstring); raises
        :class:`~scenesuggest.errors.SceneSuggestError` naming the field for a query it cannot answer."""
        ...


@dataclass(frozen=True)
class LoadContext:
    """What a study gives an engine to load from: the study's priors file (what ``paper`` and ``frequency``
    answer from), and how the study loads another engine of its own (an HTTP engine's fallback; by its
    :class:`~scenesuggest.engines.EngineSpec`)."""

    priors: Path
    load: Callable[[Any], SuggestionEngine] | None = None


class EngineKind:
    """A kind of engine, registered by name. Subclasses set ``name``, ``version`` and ``summary`` and implement
    :meth:`configure` and :meth:`load`; trainable kinds also :meth:`fit` and :meth:`train`.

    ``version`` is the kind's own version (it changes when its answers for the same file and query would); the
    export's manifest records it beside the SHA-256 of :meth:`trained_file`."""

    name: str = ""
    version: str = "1"
    summary: str = ""
    #: Whether the project can train it (``evaluate`` and ``engine train`` need this).
    trainable: bool = False

    def configure(self, options: Mapping[str, Any], base: Path | None = None) -> Any:
        """Validate a condition's options (the table without ``name``) and return them in the form :meth:`load`
        takes; relative paths are relative to ``base`` (the study file's folder). Raises
        :class:`~scenesuggest.errors.SceneSuggestError` whose ``field`` is the offending option."""
        raise NotImplementedError

    def trained_file(self, config: Any, priors: Path) -> Path | None:
        """The file this engine answers from (``priors``: the study's priors file), None if it has none."""
        return priors

    def load(self, config: Any, context: LoadContext) -> SuggestionEngine:
        raise NotImplementedError

    def problem(self, config: Any, priors: Path, current: bool = False) -> str | None:
        """What is wrong with the file this engine would answer from, if it has one of its own (missing,
        unreadable; with ``current``, made by other code), else None. Cheap: read at a server's start-up."""
        return None

    def fit(self, config: Any, scenes: list[Scene], taxonomy: Taxonomy, *, seed: int = 0,
            progress: Progress | None = None, periods: Any = None) -> SuggestionEngine:
        """An engine trained on ``scenes`` only (what ``evaluate`` asks for each fold); ``periods``: the models'
        rotational symmetry (:class:`~scenesuggest.assets.symmetry.ModelPeriods`) where known."""
        raise NotImplementedError(f"the {self.name!r} engine is not trained by this project")

    def train(self, config: Any, scenes: list[Scene], taxonomy: Taxonomy, out: Path, *, seed: int = 0,
              progress: Progress | None = None, periods: Any = None) -> dict:
        """Train on ``scenes`` and write the engine's file to ``out``; returns what was written (JSON-ready)."""
        raise NotImplementedError(f"the {self.name!r} engine is not trained by this project")

    def describe(self) -> dict:
        return {"name": self.name, "version": self.version, "summary": self.summary, "trainable": self.trainable}
