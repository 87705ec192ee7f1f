"""A copy of the demo study whose model library holds any number of models, for measuring and testing the `none`
condition's model panel with a large library.

The library is made from the demo's own (the server's, ``make demo`` builds it): its models in turn, the models the
demo scenes use first, then the rest by id; the first round keeps the original ids, each later round adds copies
under new ids (``<id>.<round>``) and names (``<name> <round>``) that share the original's GLB and thumbnail (the
``models`` and ``thumbnails`` folders are linked, not copied). The library of ``n`` models is therefore a prefix of
the library of any larger ``n``, and every scene of the demo finds its models in it. Nothing is written outside the
folder given.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from serverproc import DEMO_STUDY

STUDY_ID = "large-library"


def demo_resources() -> tuple[Path, Path]:
    """(priors file, model library folder) the demo study is served with."""
    from study_server.studies.study_file import load_study

    study = load_study(DEMO_STUDY)
    return study.priors, study.library


def scene_model_ids(study_folder: Path = DEMO_STUDY.parent) -> set[str]:
    """Ids of the models the scenes of a study folder (``scenes/*.json``) use."""
    return {o["model_id"] for f in sorted((study_folder / "scenes").glob("*.json"))
            for o in json.loads(f.read_text(encoding="utf-8"))["objects"]}


def library_models(source: Path, n: int) -> list:
    """The ``n`` models (:class:`scenesuggest.library.index.ModelInfo`) of the library made from the one in ``source``,
    in the order they were made (see the module's docstring)."""
    from scenesuggest.library.index import load_index

    originals = sorted(load_index(source).values(), key=lambda m: m.id)
    used = scene_model_ids()
    order = [m for m in originals if m.id in used] + [m for m in originals if m.id not in used]
    out = []
    for i in range(n):
        m, copy = order[i % len(order)], i // len(order)
        out.append(m if copy == 0 else replace(m, id=f"{m.id}.{copy + 1}", name=f"{m.name} {copy + 1}"))
    return out


def write_library(source: Path, folder: Path, n: int) -> Path:
    """Write a library of ``n`` models into ``folder`` (index, taxonomy, links to the source's model and thumbnail
    folders); returns ``folder``."""
    from scenesuggest.library.index import INDEX_FILE, save_index

    doc = json.loads((source / INDEX_FILE).read_text(encoding="utf-8"))
    extra = {k: v for k, v in doc.items() if k not in ("format", "version", "models")}
    save_index({m.id: m for m in library_models(source, n)}, folder, extra)
    for name in ("models", "thumbnails"):
        (folder / name).symlink_to((source / name).resolve(), target_is_directory=True)
    if (source / "taxonomy.json").is_file():
        shutil.copyfile(source / "taxonomy.json", folder / "taxonomy.json")
    return folder


def write_study(folder: Path, n: int) -> Path:
    """The demo study in ``folder`` with a library of ``n`` models, its id :data:`STUDY_ID` and its practice trial
    in the `none` condition (the model panel is then the first trial's); returns its study file."""
    priors, library = demo_resources()
    shutil.copytree(DEMO_STUDY.parent / "scenes", folder / "scenes")
    write_library(library, folder / "library", n)
    text = DEMO_STUDY.read_text(encoding="utf-8")
    practice = '[practice]\nscene = "practice"\ncondition = '
    changes = {'id = "demo"\n': f'id = "{STUDY_ID}"\n',
               'corpus = "ai2thor"\n': f'corpus = "ai2thor"\npriors = {json.dumps(str(priors))}\nlibrary = "library"\n',
               practice + '"full"\n': practice + '"none"\n'}
    for old, new in changes.items():
        if text.count(old) != 1:
            raise RuntimeError(f"the demo study file has changed: expected {old!r} once")
        text = text.replace(old, new)
    (folder / "study.toml").write_text(text, encoding="utf-8")
    return folder / "study.toml"
