"""``scenesuggest assets build``: a model library folder from a corpus.

Output layout (all generated, never committed)::

    OUT/library.json            the model index (every model of the corpus; built ones name their files)
    OUT/taxonomy.json           the corpus taxonomy
    OUT/models/<id>.glb         canonical frame: metres, +Y up, +Z front, bbox bottom centred at the origin
    OUT/thumbnails/<id>.png     256 px, transparent background

Models with a source mesh are converted (:mod:`.convert`); procedural models (AI2-THOR types) are
generated (:mod:`.procedural`); others stay in the index without an asset. The folder is built beside
``OUT`` and swapped in when complete, so a reader never sees half a library.
"""

from __future__ import annotations

import re
import shutil
import time
from dataclasses import replace
from pathlib import Path

from ..atomic import temporary_folder_beside
from ..corpora.corpus import Corpus, Progress, no_progress
from ..digest import source_digest
from ..errors import SceneSuggestError
from ..library.index import ModelInfo, save_index
from .convert import convert_model
from .procedural import procedural_model
from .render import save_thumbnail


def file_stem(model_id: str) -> str:
    """A file name for a model id (``ai2thor:Mug`` → ``ai2thor_Mug``)."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", model_id)


def buildable(model: ModelInfo) -> bool:
    return model.size_source == "procedural" or model.mesh is not None


def build_model(model: ModelInfo, out: Path, thumbnail_px: int = 256) -> ModelInfo:
    """Write one model's GLB and thumbnail under ``out``; returns its index entry with the file paths."""
    stem = file_stem(model.id)
    glb = Path("models") / f"{stem}.glb"
    png = Path("thumbnails") / f"{stem}.png"
    if model.size_source == "procedural":
        scene = procedural_model(model.category, model.size)
        (out / glb).write_bytes(scene.export(file_type="glb"))
    elif model.mesh is not None:
        scene = convert_model(model, model.mesh, out / glb)
    else:
        raise SceneSuggestError(f"model {model.id!r} has no mesh to build from", field="models")
    save_thumbnail(scene, out / png, thumbnail_px)
    return replace(model, asset=glb.as_posix(), thumbnail=png.as_posix())


#: The modules that build a library's assets (not the symmetry measure, which reads them).
#: What decides a library's files: the asset builders, and the corpus loaders that size each model (an AI2-THOR
#: model's box is its type's median box as the loader reads it).
BUILDERS = ("assets/__init__.py", "assets/build.py", "assets/convert.py", "assets/primitives.py",
            "assets/procedural.py", "assets/render.py", "corpora/*.py")


def code_digest() -> str:
    """A short hash of the asset builders' code: a library built by other code is rebuilt by ``study prepare``."""
    return source_digest(*BUILDERS)


def build_library(corpus: Corpus, out: str | Path, model_ids: list[str] | None = None, thumbnail_px: int = 256,
                  progress: Progress = no_progress) -> dict:
    """Build the assets of ``model_ids`` (default: every buildable model) into ``out``; returns a report
    with counts and timings (seconds)."""
    out = Path(out)
    if model_ids is not None:
        unknown = [m for m in model_ids if m not in corpus.models]
        if unknown:
            raise SceneSuggestError(f"unknown model ids: {', '.join(unknown[:5])}", field="models")
        todo = [corpus.models[m] for m in model_ids]
    else:
        todo = [m for m in corpus.models.values() if buildable(m)]
    tmp = temporary_folder_beside(out)
    started = time.perf_counter()
    timings: dict[str, float] = {}
    try:
        (tmp / "models").mkdir()
        (tmp / "thumbnails").mkdir()
        index = dict(corpus.models)
        for model in progress(todo, "building assets"):
            t = time.perf_counter()
            index[model.id] = build_model(model, tmp, thumbnail_px)
            timings[model.id] = time.perf_counter() - t
        save_index(index, tmp, extra={"source": corpus.source, "code": code_digest()})
        corpus.taxonomy.save(tmp / "taxonomy.json")
        _swap_in(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    sizes = [(out / index[m].asset).stat().st_size for m in timings]
    return {
        "out": str(out),
        "built": len(timings),
        "skipped": sum(1 for m in corpus.models.values() if not buildable(m)) if model_ids is None else 0,
        "seconds": time.perf_counter() - started,
        "per_model_s": sum(timings.values()) / len(timings) if timings else 0.0,
        "max_glb_bytes": max(sizes, default=0),
    }


def _swap_in(new: Path, out: Path) -> None:
    """Replace ``out`` by the complete folder ``new`` (the old one is removed only after the swap)."""
    if out.exists():
        old = out.with_name(f".{out.name}-old-{time.time_ns()}")
        out.rename(old)
        new.rename(out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        new.rename(out)
