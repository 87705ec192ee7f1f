"""Scene corpora: ``stanford:DIR``, ``ai2thor`` and ``json:DIR``, all converted to the world frame."""

from __future__ import annotations

from pathlib import Path

from ..errors import SceneSuggestError
from .corpus import Corpus, Progress, no_progress

__all__ = ["Corpus", "load_corpus", "SOURCES"]

SOURCES = ("stanford:DIR", "ai2thor", "json:DIR")


def load_corpus(source: str, *, meshes: str | Path | None = None, progress: Progress = no_progress) -> Corpus:
    """Load a corpus named by a source string (see ``SOURCES``); ``meshes`` is the Stanford mesh folder."""
    kind, _, arg = source.partition(":")
    if kind == "ai2thor" and not arg:
        from .ai2thor import load_ai2thor

        return load_ai2thor(progress=progress)
    if kind in ("stanford", "json") and arg:
        try:
            folder = Path(arg).is_dir()
        except (OSError, ValueError):  # a name too long for the file system, a NUL
            folder = False
        if not folder:
            shown = arg if arg.isprintable() and len(arg) <= 200 else repr(arg[:200]) + ("…" if len(arg) > 200 else "")
            raise SceneSuggestError(f"no such folder: {shown}", field="source")
        if kind == "stanford":
            from .stanford import load_stanford

            return load_stanford(arg, meshes=meshes, progress=progress)
        from .native import load_native

        return load_native(arg, progress=progress)
    raise SceneSuggestError(f"unknown corpus source {source!r}; expected one of: {', '.join(SOURCES)}",
                            field="source")
