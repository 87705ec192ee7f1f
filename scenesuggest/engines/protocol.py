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

An engine that waits on another process (the ``http`` engine) takes one of a server's :class:`WaitSlots` while it
waits, so that waits never hold more than a share of the server's workers.
"""

from __future__ import annotations

import contextlib
import os
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


class WaitSlots:
    """At most ``count`` queries wait on engines at once among the processes sharing ``folder`` (one server's
    workers): a query holds an exclusive lock on one of ``count`` files while it is sent and answered, and one that
    finds every file locked gets the fallback's list at once. A sync worker waiting on an engine serves nobody
    else, so this keeps the rest of a server's workers for everyone else however slow the engine is. The kernel
    drops a process's locks when it dies: a killed worker holds no slot."""

    def __init__(self, folder: str | Path, count: int):
        self.folder, self.count = Path(folder), count

    @contextlib.contextmanager
    def held(self):
        """Yields whether a slot was free (and holds it meanwhile)."""
        import fcntl

        held = None
        try:
            self.folder.mkdir(mode=0o700, parents=True, exist_ok=True)  # a cleaner of /tmp may have taken it
            for i in range(self.count):
                fd = os.open(self.folder / f"slot-{i}", os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o600)
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    os.close(fd)
                    continue
                held = fd
                break
        except OSError:  # no folder, no file descriptor left: this query is not bounded rather than refused
            held = -1
        try:
            yield held is not None
        finally:
            if held is not None and held >= 0:
                os.close(held)  # closing the file releases the lock
