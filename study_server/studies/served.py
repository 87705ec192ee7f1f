"""The studies a server runs: each study file loaded and validated at start-up (a bad study stops the server,
never a participant's request), with what a running study needs besides the database — its engine per condition,
model library, search index and scenes — and the lookup of a study by id per request.

The pieces are loaded once per process, lazily (the first request that needs a piece loads it, under a lock), so
that creating the app stays cheap and each gunicorn worker holds one copy.
"""

from __future__ import annotations

import dataclasses
import json
import threading
from functools import cached_property, partial
from pathlib import Path

from flask import abort, current_app, request, url_for

from scenesuggest import engines
from scenesuggest.assets.symmetry import NONE, corpus_periods
from scenesuggest.engines.protocol import LoadContext, SuggestionEngine
from scenesuggest.learning.priors import Priors
from scenesuggest.library.index import INDEX_FILE, ModelInfo, load_index
from scenesuggest.library.search import SearchIndex
from scenesuggest.scenes import scene_json
from scenesuggest.scenes.taxonomy import Taxonomy
from scenesuggest.suggestion.suggestable import suggestable

from ..base import i18n
from .study_file import Study, StudyFileError, load_study


class EngineNotLoaded(Exception):
    """A condition's engine cannot be loaded (its file is damaged, say): the server's fault, not the caller's, so no
    :class:`study_server.base.errors.StudyError` — its message names files and is for the server's log and /healthz
    (:class:`study_server.trials.lists.SuggestionsUnavailable` is what a participant is told)."""


def load_studies(files: list[Path], check: bool = True) -> dict[str, StudyRuntime]:
    """Validate every study file (and, with ``check``, its scenes, priors and library): a bad study stops
    the server at start-up with an error naming the key, never a participant's request."""
    runtimes: dict[str, StudyRuntime] = {}
    for f in files:
        study = load_study(f)
        if study.id in runtimes:
            raise StudyFileError(f"study id {study.id!r} is used by two study files", file=str(f), field="id")
        runtime = StudyRuntime(study)
        runtime.validate_scenes()
        if check:
            runtime.check_resources()
        runtimes[study.id] = runtime
    return runtimes


def runtime(study_id: str) -> StudyRuntime:
    studies = current_app.extensions["studies"]
    if study_id not in studies:
        abort(404)
    return studies[study_id]


class StudyRuntime:
    """One study as the server runs it: its validated file and, loaded on first use, its resources."""

    def __init__(self, study: Study):
        self.study = study
        self._lock = threading.RLock()
        self._engines: dict[str, SuggestionEngine] = {}
        #: Why a condition's engine could not be loaded, by condition (until it loads).
        self.engine_failures: dict[str, str] = {}
        self._placeable: dict[str, frozenset[str]] = {}
        self._periods: dict[str, float] = {}
        #: What the API says of each model, by id, its URLs below the app's mount point: made once, as a model's
        #: size is computed from its bounding box and its URLs by routing (a sixth of a suggestion request's CPU).
        #: Bounded by the library: one entry per model.
        self.model_descriptions: dict[str, dict] = {}
        #: Scene files by path: the version they were read at (inode, mtime, ctime, size), their text and their JSON
        #: (:meth:`_document`); under a lock of their own, so that reading a scene never waits for an engine to load.
        self._documents: dict[Path, tuple[tuple[int, int, int, int], str, dict]] = {}
        self._documents_lock = threading.Lock()

    def describe(self, m: ModelInfo, language: str | None = None) -> dict:
        """What the API says of model ``m`` (size in metres, asset and thumbnail URLs, its category's name in
        ``language``, default the page's), in a request context: a new dict each call. Made once per model
        (:attr:`model_descriptions`, URLs below the mount point, which is prefixed per request)."""
        prefix = request.script_root
        d = self.model_descriptions.get(m.id)
        if d is None:
            d = self.model_descriptions[m.id] = {
                "id": m.id, "name": m.name, "category": m.category, "category_path": tuple(m.category_path),
                "tags": tuple(m.tags), "size": tuple(m.size),
                **{key: url_for("participant.asset", study_id=self.study.id, filename=name)[len(prefix):]
                   for key, name in (("asset", m.asset), ("thumbnail", m.thumbnail))}}
        label = i18n.category_label(m.category, language or i18n.page_language())  # the participant's, if any
        return {**d, "asset": prefix + d["asset"], "thumbnail": prefix + d["thumbnail"], "label": label or m.name}

    def check_resources(self) -> None:
        """Fail at start-up, naming the key, when the priors file or the model library is missing or unreadable
        (:func:`.prepare.problems`), saying how to make it."""
        from .prepare import problems

        s = self.study
        for key, problem in problems(s).items():
            if key.startswith("conditions["):
                raise StudyFileError(problem, file=str(s.path), field=key)
            if s.server_resources:
                how = f"build it with 'scenesuggest study prepare {s.path}'"
            elif key == "priors":
                how = f"make it with 'scenesuggest priors train {s.corpus} -o {s.priors}'"
            else:
                how = f"build it with 'scenesuggest assets build {s.corpus} --out {s.library}'"
            raise StudyFileError(f"{problem}: {how}", file=str(s.path), field=f"resources.{key}")

    def warm(self) -> None:
        """Load now what the first requests would otherwise load (priors, library, search index, taxonomy and
        each suggesting condition's engine): a served process does this before it takes a request, so the first
        participant's click costs what every other does (the priors alone took a quarter of a second). A file
        that cannot be loaded stops the start-up with a :class:`StudyFileError` naming it."""
        s = self.study
        for key, load in (("priors", lambda: self.priors), ("library", lambda: self.search_index)):
            try:
                load()
            except Exception as e:  # noqa: BLE001 - any failure to read it, said with the file and the key
                raise StudyFileError(f"cannot be loaded ({type(e).__name__}: {e})", file=str(s.path),
                                     field=f"resources.{key}") from None
        _ = self.taxonomy  # a cached property: loaded on first read
        for i, c in enumerate(s.conditions):
            if c.mode:
                try:
                    self.placeable(c.id)
                except EngineNotLoaded as e:
                    raise StudyFileError(str(e.__cause__ or e), file=str(s.path),
                                         field=f"conditions[{i}].engine") from None

    @cached_property
    def priors(self) -> Priors:
        with self._lock:
            return Priors.load(self.study.priors)

    def engine(self, condition_id: str) -> SuggestionEngine:
        """The engine of a condition (:mod:`scenesuggest.engines`), loaded once. An engine that cannot be loaded
        raises :class:`EngineNotLoaded` (and is tried again at the next request); why is kept for /healthz and
        the server's log, never told to a participant."""
        with self._lock:
            if condition_id not in self._engines:
                spec = self.study.condition(condition_id).engine
                try:
                    self._engines[condition_id] = self.load_engine(spec)
                except Exception as e:  # noqa: BLE001 - any failure to read or build it
                    self.engine_failures[condition_id] = f"{type(e).__name__}: {e}"
                    raise EngineNotLoaded(f"the {spec.name} engine of the condition {condition_id!r} cannot be "
                                            f"loaded: {type(e).__name__}: {e}") from e
                self.engine_failures.pop(condition_id, None)
                loaded = self._engines[condition_id]
                if hasattr(loaded, "breaker"):  # an http engine: its circuit's changes go in the study's log, and
                    loaded.breaker.on_change = partial(self._circuit_changed, condition_id)
                    loaded.slots = engine_wait_slots()  # at most half the server's workers wait on engines
            return self._engines[condition_id]

    def _circuit_changed(self, condition_id: str, state: str, detail: dict) -> None:
        """Log an http engine's circuit opening or closing (the admin's dashboard shows the last of each
        condition), in the transaction of the request that saw it."""
        from flask import has_app_context

        from ..base.models import log

        if has_app_context():
            log("engine_circuit", None, study_id=self.study.id, condition=condition_id, state=state, **detail)

    def loaded_engines(self) -> dict[str, SuggestionEngine]:
        """The engines loaded so far, by condition (nothing is loaded by asking)."""
        with self._lock:
            return dict(self._engines)

    def load_engine(self, spec: engines.EngineSpec) -> SuggestionEngine:
        """An engine of this study: those that answer from the study's priors file share its one copy."""
        kind, priors = spec.kind, self.study.priors
        if hasattr(kind, "from_priors") and kind.trained_file(spec.config, priors) == priors:
            return kind.from_priors(spec.config, self.priors)
        return kind.load(spec.config, LoadContext(priors, load=self.load_engine))

    def engine_files(self) -> dict[str, dict]:
        """Per condition that suggests: its engine's name, version and trained file (the manifest's record)."""
        out = {}
        for c in self.study.conditions:
            if c.mode is None:
                continue
            spec = c.engine
            out[c.id] = {"engine": spec.name, "version": spec.kind.version,
                         "options": {k: v for k, v in spec.raw.items() if k != "name"},
                         "file": spec.kind.trained_file(spec.config, self.study.priors)}
        return out

    def placeable(self, condition_id: str) -> frozenset[str]:
        """The engine's categories that this study's library has a model of (the ones worth suggesting)."""
        with self._lock:
            if condition_id not in self._placeable:
                engine = self.engine(condition_id)
                # a plugin engine's list may hold a placeholder: never offered
                self._placeable[condition_id] = frozenset(
                    name for name, members in engine.categories.items() if suggestable(name)
                    and (any(m in self.library for m in members) or name in self.by_category))
            return self._placeable[condition_id]

    @cached_property
    def library(self) -> dict[str, ModelInfo]:
        """Models of the study's library that have an asset (the ones a participant can place)."""
        return {m.id: m for m in load_index(self.study.library).values() if m.asset}

    @cached_property
    def by_category(self) -> dict[str, list[ModelInfo]]:
        out: dict[str, list[ModelInfo]] = {}
        for m in self.fixed_list:
            out.setdefault(m.category, []).append(m)
        return out

    @cached_property
    def fixed_list(self) -> list[ModelInfo]:
        """The ``none`` condition's panel: every model, in a fixed order (category path, then name)."""
        return sorted(self.library.values(), key=lambda m: ([c.lower() for c in m.category_path], m.name, m.id))

    @cached_property
    def search_index(self) -> SearchIndex:
        """Keyword search over the study's models, which finds a model by its category's name in each of the
        study's languages too (a German participant searches for "Stuhl")."""
        names = [i18n.category_names(language) for language in self.study.languages]
        return SearchIndex.build([dataclasses.replace(m, tags=[*m.tags, *(n[m.category] for n in names
                                                                          if m.category in n)])
                                  for m in self.fixed_list])

    @cached_property
    def taxonomy(self) -> Taxonomy:
        """The categories' taxonomy: the one the model library was built with, else the priors'."""
        path = self.study.library / "taxonomy.json"
        if path.is_file():
            return Taxonomy.load(path)
        return self.priors.taxonomy if self.study.priors.is_file() else Taxonomy()

    def period_of(self, model_id: str) -> float:
        """The model's rotational symmetry period (degrees about its up axis; 360: none), measured on its asset
        once (and cached on disk, :mod:`scenesuggest.assets.symmetry`)."""
        with self._lock:
            known = self._periods.get(model_id)
        if known is None:  # measured outside the lock, which suggestions wait on (twice at worst, alike)
            model = self.library.get(model_id) if (self.study.library / INDEX_FILE).is_file() else None
            found = corpus_periods([model], base=self.study.library) if model else None
            known = found.of(model_id, model.category)[0] if found else NONE
            with self._lock:
                self._periods[model_id] = known
        return known

    def _document(self, path: Path) -> tuple[str, dict]:
        """The scene file at ``path``: its text and its parsed JSON, read again only when the file has changed since
        (another inode, modification or change time, or size: an admin may author a target while the server runs,
        in any of its processes, and saves replace the file). The parsed JSON is shared: read it, never change it."""
        stat = path.stat()
        version = (stat.st_ino, stat.st_mtime_ns, stat.st_ctime_ns, stat.st_size)
        with self._documents_lock:
            known = self._documents.get(path)
        if known is not None and known[0] == version:
            return known[1], known[2]
        text = path.read_text()
        doc = json.loads(text)
        with self._documents_lock:
            self._documents[path] = (version, text, doc)
        return text, doc

    def scene(self, scene_id: str, which: str = "target") -> dict:
        """A target (or start) scene as native JSON, parsed afresh (the caller may change it); the start defaults
        to the target's room alone."""
        s = self.study.scenes[scene_id]
        if which == "start" and s.start is not None:
            return json.loads(self._document(Path(s.start))[0])
        doc = json.loads(self._document(Path(s.target))[0])
        if which == "start":
            doc["objects"] = [o for o in doc["objects"] if o.get("parent") is None]
        return doc

    def scene_type(self, scene_id: str) -> str:
        """The scene type of a scene (its target's ``scene_type``; ``Room`` when it names none): what the
        engine's occurrence priors are conditioned on."""
        return self._document(Path(self.study.scenes[scene_id].target))[1].get("scene_type", "Room")

    def validate_scenes(self) -> None:
        """Parse every scene file (a bad one stops the start-up naming it), and keep them parsed."""
        for s in self.study.scenes.values():
            scene_json.load(s.target)
            self._document(Path(s.target))
            if s.start:
                scene_json.load(s.start)
                self._document(Path(s.start))


#: The share of a server's workers that may wait on http engines at once (the others serve everyone else).
ENGINE_WAIT_SHARE = 0.5


def engine_wait_slots():
    """The wait slots shared by this server's workers (``study_server.base.gunicorn_settings``: at most
    ENGINE_WAIT_SHARE of them, at least one), None when not served by gunicorn that way (one process)."""
    import math
    import os

    from scenesuggest.engines.protocol import WaitSlots

    from ..base.gunicorn_settings import WAITS, WORKERS

    folder, workers = os.environ.get(WAITS), os.environ.get(WORKERS, "1")
    if not folder or not os.path.isdir(folder) or not workers.isdigit():
        return None
    return WaitSlots(folder, max(1, math.floor(int(workers) * ENGINE_WAIT_SHARE)))
