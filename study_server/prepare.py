"""Building what a study file names but does not find: its priors file and model library, from its corpus.

``scenesuggest study prepare`` (and ``study serve``, before it starts) builds them, so that a server installed
from the package serves the built-in demo with no other step. A priors file that this engine cannot read (an
older version) is trained again. Both are written whole or not at all (the library into a temporary folder that is
renamed, the priors file by :meth:`scenesuggest.priors.Priors.save`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from scenesuggest.errors import SceneSuggestError
from scenesuggest.library import INDEX_FILE
from scenesuggest.priors import Priors

from .study_file import Study

Progress = Callable[[Iterable, str], Iterable]


def missing(study: Study) -> list[str]:
    """What the study lacks: ``"library"`` and/or ``"priors"`` (missing, or a priors file of another version)."""
    out = []
    if not (study.library / INDEX_FILE).is_file():
        out.append("library")
    try:
        Priors.load(study.priors)
    except SceneSuggestError:
        out.append("priors")
    return out


def prepare(study: Study, progress: Progress, say: Callable[[str], None]) -> list[str]:
    """Build what :func:`missing` names from the study's corpus; returns what was built."""
    todo = missing(study)
    if not todo:
        return []
    from scenesuggest.corpora import load_corpus

    say(f"{study.id}: building its {' and '.join(todo)} from the corpus {study.corpus!r} (a few minutes, once)")
    corpus = load_corpus(study.corpus, progress=progress)
    if "library" in todo:
        from scenesuggest.assets.build import build_library

        build_library(corpus, study.library, progress=progress)
        say(f"{study.id}: model library → {study.library}")
    if "priors" in todo:
        study.priors.parent.mkdir(parents=True, exist_ok=True)
        Priors.fit(corpus.scenes, corpus.taxonomy, progress=progress).save(study.priors)
        say(f"{study.id}: priors → {study.priors}")
    return todo
