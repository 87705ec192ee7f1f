"""The studies a server runs: loaded and validated at start-up, looked up by id per request."""

from __future__ import annotations

from pathlib import Path

from flask import abort, current_app

from .services import StudyRuntime
from .study_file import StudyFileError, load_study


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
