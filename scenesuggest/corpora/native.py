"""``json:DIR`` — a corpus in the native format, and writing any corpus in it.

Layout: ``DIR/scenes/*.json`` (one scene each, see :mod:`scenesuggest.scenes.scene_json`), ``DIR/taxonomy.json``
(``{"parents": {category: parent}}``) and ``DIR/library.json`` (the model index), both optional.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from ..atomic import temporary_folder_beside
from ..errors import SceneSuggestError
from ..library.index import INDEX_FILE, ModelInfo, load_index, save_index
from ..scenes import scene_json
from ..scenes.taxonomy import Taxonomy
from .corpus import Corpus, Progress, no_progress

TAXONOMY_FILE = "taxonomy.json"


def load_native(directory: str | Path, progress: Progress = no_progress) -> Corpus:
    root = Path(directory)
    scene_dir = root / "scenes" if (root / "scenes").is_dir() else root
    files = sorted(p for p in scene_dir.glob("*.json") if p.name not in (TAXONOMY_FILE, INDEX_FILE))
    if not files:
        raise SceneSuggestError("no scenes found (expected scenes/*.json)", file=str(root))
    scenes = [scene_json.load(p) for p in progress(files, "reading scenes")]
    taxonomy = Taxonomy.load(root / TAXONOMY_FILE) if (root / TAXONOMY_FILE).is_file() else Taxonomy()
    models = load_index(root) if (root / INDEX_FILE).is_file() else {}
    for scene in scenes:
        for o in scene:
            if o.model_id not in models:
                sx, sy, sz = o.size
                models[o.model_id] = ModelInfo(
                    id=o.model_id, category=o.category, category_path=taxonomy.path(o.category),
                    raw_bbox=((-sx / 2, 0.0, -sz / 2), (sx / 2, sy, sz / 2)), size_source="scene")
    return Corpus(f"json:{root}", scenes, models, taxonomy)


def write_native(corpus: Corpus, directory: str | Path, progress: Progress = no_progress) -> Path:
    """Write ``corpus`` to ``directory`` in the native format, all or nothing: files are written to a
    temporary folder beside it, which replaces ``directory`` only when complete."""
    target = Path(directory)
    if target.exists() and any(target.iterdir()):
        raise SceneSuggestError("output folder exists and is not empty", file=str(target))
    tmp = temporary_folder_beside(target)
    try:
        (tmp / "scenes").mkdir()
        for scene in progress(corpus.scenes, "writing scenes"):
            scene_json.save(scene, tmp / "scenes" / f"{scene.id}.json")
        corpus.taxonomy.save(tmp / TAXONOMY_FILE)
        save_index(corpus.models, tmp)
        if target.exists():
            target.rmdir()
        tmp.rename(target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target
