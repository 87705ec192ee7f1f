"""Whether a study has the priors file and model library it needs, and building the server's own.

A study file either names its priors file and model library (made by ``scenesuggest priors train`` and ``assets
build``, or by the study's own preparation, as the replication's) or names only its corpus and uses the server's
own for it, in the server's data folder (:func:`..base.config.data_home`). The server only ever builds its own:
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
from scenesuggest.learning.priors import Priors, code_digest
from scenesuggest.library.index import INDEX_FILE

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


def condition_engines(study: Study):
    """(key, engine spec) of every engine a condition uses: its own and, for an http engine, its fallback."""
    for i, c in enumerate(study.conditions):
        key, spec = f"conditions[{i}].engine", c.engine
        yield key, spec
        fallback = getattr(spec.config, "fallback", None)
        if fallback is not None:
            yield f"{key}.fallback", fallback


def engine_problems(study: Study, current: bool = False) -> dict[str, str]:
    """Engines that answer from a file of their own (the learned engine's) that is missing or unreadable (key: the
    condition's ``engine`` key), or, with ``current``, was trained by other code."""
    out = {}
    for key, spec in condition_engines(study):
        problem = spec.kind.problem(spec.config, study.priors, current)
        if problem:
            path = spec.kind.trained_file(spec.config, study.priors)
            how = (f"'scenesuggest study prepare {study.path}'" if study.server_resources and _default_file(spec, study)
                   else f"'scenesuggest engine train {spec.name} {study.corpus} -o {path}'")
            out[key] = f"{problem}: make it with {how}"
    return out


def prepare(study: Study, progress: Progress, say: Callable[[str], None]) -> list[str]:
    """Build the server's own priors, library and engine files (a learned engine's, when a condition names no
    file of its own) for the study's corpus where :func:`problems` finds them missing or stale; returns what was
    built (nothing for a study that names its own, and never a file a study file names)."""
    if not study.server_resources:
        return []
    own = {key for key, spec in condition_engines(study) if _default_file(spec, study)}
    todo = sorted(k for k in problems(study, current=True) if not k.startswith("conditions[") or k in own)
    if not todo:
        return []
    from scenesuggest.corpora import load_corpus

    what = sorted({"engines' files" if k.startswith("conditions[") else k for k in todo})
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
    built: set = set()
    periods = None
    for key, spec in condition_engines(study):
        path = spec.kind.trained_file(spec.config, study.priors)
        if key in todo and path not in built:
            from scenesuggest.assets.symmetry import corpus_periods

            periods = periods or corpus_periods(corpus.models.values(), progress)
            spec.kind.train(spec.config, corpus.scenes, corpus.taxonomy, path, progress=progress, periods=periods)
            built.add(path)
            say(f"{study.id}: {spec.name} engine → {path}")
    return todo


def _default_file(spec, study: Study) -> bool:
    """Whether an engine answers from the server's own file for it (its kind's default beside the server's
    priors), which the server may build — never a file the study file names."""
    path = spec.kind.trained_file(spec.config, study.priors)
    if path is None or path == study.priors:
        return False
    try:
        return path == spec.kind.trained_file(spec.kind.configure({}), study.priors)
    except SceneSuggestError:  # a kind that needs options (http) has no file of its own
        return False
