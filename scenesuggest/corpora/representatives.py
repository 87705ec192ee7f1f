"""A study's model corpus as the paper built it: one representative model per most frequent category.

A representatives file is tab-separated with a header ``category<TAB>model_id<TAB>instances_in_corpus``
(the third column optional). Without one, :func:`top_representatives` applies the same rule to a corpus: for
each of the ``n`` categories with the most object instances, the most used model of that category that has a
mesh (ties broken by model id).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from ..errors import SceneSuggestError
from .corpus import Corpus

FILE_NAME = "representatives.tsv"


def read_representatives(path: str | Path) -> list[tuple[str, str]]:
    """(category, model id) rows of a representatives file, in file order."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise SceneSuggestError(f"cannot read: {e}", file=str(path)) from None
    if not lines or lines[0].split("\t")[:2] != ["category", "model_id"]:
        raise SceneSuggestError("expected a header 'category<TAB>model_id'", file=str(path), line=1)
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        cells = line.split("\t")
        if len(cells) < 2 or not cells[0].strip() or not cells[1].strip():
            raise SceneSuggestError("expected 'category<TAB>model_id'", file=str(path), line=number)
        rows.append((cells[0].strip(), cells[1].strip()))
    return rows


def top_representatives(corpus: Corpus, n: int = 100) -> list[tuple[str, str]]:
    """(category, model id) for the ``n`` most frequent categories of ``corpus`` that have a model with a mesh."""
    per_category: Counter[str] = Counter()
    per_model: Counter[tuple[str, str]] = Counter()
    for scene in corpus.scenes:
        for o in scene:
            if o.parent is None:
                continue
            per_category[o.category] += 1
            per_model[(o.category, o.model_id)] += 1
    out = []
    for category, _ in sorted(per_category.items(), key=lambda kv: (-kv[1], kv[0])):
        with_mesh = [(count, model_id) for (c, model_id), count in per_model.items()
                     if c == category and corpus.models.get(model_id) is not None
                     and corpus.models[model_id].mesh is not None]
        if with_mesh:
            out.append((category, min(with_mesh, key=lambda cm: (-cm[0], cm[1]))[1]))
        if len(out) == n:
            break
    return out


def study_representatives(corpus: Corpus, mesh_dir: Path | None,
                          path: str | Path | None = None) -> tuple[list[tuple[str, str]], str]:
    """The (category, model id) rows a study's library is built from, and where they came from: ``path`` if
    given, else the representatives file beside the mesh folder, else :func:`top_representatives` (100). Every
    model named in a file must have a mesh."""
    file = Path(path) if path else mesh_dir.parent / FILE_NAME if mesh_dir else None
    if file is None or not (path or file.is_file()):
        return top_representatives(corpus, 100), "chosen from the corpus (top 100 categories)"
    rows = read_representatives(file)
    missing = [m for _, m in rows if m not in corpus.models or corpus.models[m].mesh is None]
    if missing:
        raise SceneSuggestError(f"{len(missing)} representative model(s) have no mesh, e.g. {missing[0]}",
                                file=str(file))
    return rows, str(file)
