"""Whether a study has the priors file and model library it needs, and building the server's own.

A study file either names its priors file and model library (made by ``scenesuggest priors train`` and ``assets
build``, or by the study's own preparation, as the replication's) or names only its corpus and uses the server's
own for it, in the server's data folder (:func:`.config.data_home`). The server only ever builds its own:
``scenesuggest study prepare`` (and ``study serve``, before it starts) builds them when they are missing, cannot be
read by this engine, or were made by other engine code — so that a server installed from the package serves the
built-in demo with no other step. What a study file names is never overwritten: a problem with it stops the server
at start-up with a message saying how to make it. Both are written whole or not at all.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable

from scenesuggest.assets.build import code_digest as assets_digest
from scenesuggest.errors import SceneSuggestError
from scenesuggest.library import INDEX_FILE
from scenesuggest.priors import Priors, code_digest

from .study_file import Study

Progress = Callable[[Iterable, str], Iterable]


def problems(study: Study, current: bool = False) -> dict[str, str]:
    """What is wrong with the study's ``library`` and ``priors`` (key → message; empty when nothing). Cheap: the
    priors' metadata is read, not its arrays. With ``current``, also what other engine code made."""
    out = {}
    try:
        meta = Priors.read_meta(study.priors)
        if current and meta.get("code") != code_digest():
            out["priors"] = f"the priors file {study.priors} was trained by other engine code"
    except SceneSuggestError as e:
        out["priors"] = f"no usable priors file at {study.priors} ({e.message})"
    index = study.library / INDEX_FILE
    try:
        library = json.loads(index.read_text(encoding="utf-8"))
        if current and library.get("code") != assets_digest():
            out["library"] = f"the model library at {study.library} was built by other code"
    except (OSError, ValueError, AttributeError):
        out["library"] = f"no model library at {study.library}"
    out.update(engine_problems(study, current))
    return out


def engine_problems(study: Study, current: bool = False) -> dict[str, str]:
    """Conditions whose engine answers from a file of its own (the learned engine's) that is missing or unreadable
    (key: the condition's ``engine`` key), or, with ``current``, was trained by other code."""
    out = {}
    for i, c in enumerate(study.conditions):
        spec = c.engine
        target = spec.config.fallback if spec.name == "http" else spec
        if target.name != "learned":
            continue
        from scenesuggest.engines.learned import LearnedEngine
        from scenesuggest.engines.learned.engine import code_digest as learned_digest

        path = target.kind.trained_file(target.config, study.priors)
        key = f"conditions[{i}].engine" + (".fallback" if target is not spec else "")
        try:
            meta = LearnedEngine.read_meta(path)
            if current and meta.get("code") != learned_digest():
                out[key] = f"the learned engine's file {path} was trained by other engine code"
        except SceneSuggestError as e:
            how = (f"'scenesuggest study prepare {study.path}'" if study.server_resources else
                   f"'scenesuggest engine train learned {study.corpus} -o {path}'")
            out[key] = f"no usable learned engine's file at {path} ({e.message}): make it with {how}"
    return out


def prepare(study: Study, progress: Progress, say: Callable[[str], None]) -> list[str]:
    """Build the server's own priors and library for the study's corpus where :func:`problems` finds them
    missing or stale; returns what was built (nothing for a study that names its own)."""
    if not study.server_resources:
        return []
    todo = sorted(problems(study, current=True))
    if not todo:
        return []
    from scenesuggest.corpora import load_corpus

    what = sorted({"learned engine" if k.startswith("conditions[") else k for k in todo})
    say(f"{study.id}: building the {' and '.join(what)} of the corpus {study.corpus!r} (about a minute each, once)")
    corpus = load_corpus(study.corpus, progress=progress)
    if "library" in todo:
        from scenesuggest.assets.build import build_library

        build_library(corpus, study.library, progress=progress)
        say(f"{study.id}: model library → {study.library}")
    if "priors" in todo:
        study.priors.parent.mkdir(parents=True, exist_ok=True)
        Priors.fit(corpus.scenes, corpus.taxonomy, progress=progress).save(study.priors)
        say(f"{study.id}: priors → {study.priors}")
    built = set()
    for key in todo:
        if key.startswith("conditions["):
            spec = study.condition(study.conditions[int(key[11:key.index("]")])].id).engine
            spec = spec.config.fallback if spec.name == "http" else spec
            path = spec.kind.trained_file(spec.config, study.priors)
            if path not in built:
                from scenesuggest.symmetry import corpus_periods

                spec.kind.train(spec.config, corpus.scenes, corpus.taxonomy, path, progress=progress,
                                periods=corpus_periods(corpus.models.values(), progress))
                built.add(path)
                say(f"{study.id}: learned engine → {path}")
    return todo
