"""ShapeNetSem metadata and 3D Warehouse text fields of the Stanford Scene Database models.

``StanfordModelDB_MetaInfo*.csv`` has no header; its columns are, in order: fullId (``wss.<id>``),
category (comma list, mostly coarse→fine; ``_``-prefixed entries are bookkeeping), wnsynset, wnlemmas,
up, front (``"x\\,y\\,z"``), unit (model units → metres), aligned.dims (cm, along the model's
right, up and front axes), isContainerLike, surfaceVolume, solidVolume, supportSurfaceArea, weight,
staticFrictionForce, name, tags.
"""

from __future__ import annotations

import csv
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from ..errors import SceneSuggestError

#: Defaults when a model has no up/front in the metadata (the Stanford Scene Database convention).
DEFAULT_UP = (0.0, 0.0, 1.0)
DEFAULT_FRONT = (0.0, -1.0, 0.0)
#: Stanford model units are inches unless the metadata says otherwise.
DEFAULT_UNIT = 0.0254
N_COLUMNS = 16


@dataclass
class ModelMeta:
    id: str
    labels: list[str]  # category labels as listed (bookkeeping entries removed)
    wnsynset: str
    wnlemmas: list[str]
    up: tuple[float, float, float] | None
    front: tuple[float, float, float] | None
    unit: float | None
    dims_cm: tuple[float, float, float] | None  # along (right, up, front)
    name: str
    tags: list[str]


def _is_bookkeeping(label: str) -> bool:
    # "_StanfordSceneDBModels", "_OIMwhitelist", and ranking lists such as "rankChairs"
    return label.startswith("_") or re.fullmatch(r"rank[A-Z]\w*", label) is not None


def _vector(text: str, file: str, line: int, field: str, n: int) -> tuple[float, ...] | None:
    text = text.strip()
    if not text:
        return None
    parts = [p for p in re.split(r"\\?,", text) if p != ""]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise SceneSuggestError(f"bad number in {text!r}", file=file, line=line, field=field) from None
    if len(values) != n:
        raise SceneSuggestError(f"expected {n} numbers, got {len(values)}", file=file, line=line, field=field)
    return values


def read_metadata(path: str | Path) -> dict[str, ModelMeta]:
    """Parse a ShapeNetSem metadata CSV into ``{model id: ModelMeta}`` (ids without the ``wss.`` prefix)."""
    path = Path(path)
    out: dict[str, ModelMeta] = {}
    file = str(path)
    try:
        with path.open(newline="", encoding="utf-8") as f:
            for line_no, row in enumerate(csv.reader(f), start=1):
                if not row:
                    continue
                if len(row) != N_COLUMNS:
                    raise SceneSuggestError(f"expected {N_COLUMNS} columns, got {len(row)}", file=file,
                                            line=line_no)
                full_id = row[0]
                model_id = full_id[4:] if full_id.startswith("wss.") else full_id
                unit = None
                if row[6].strip():
                    try:
                        unit = float(row[6])
                    except ValueError:
                        raise SceneSuggestError(f"bad number {row[6]!r}", file=file, line=line_no,
                                                field="unit") from None
                out[model_id] = ModelMeta(
                    id=model_id,
                    labels=[c for c in row[1].split(",") if c and not _is_bookkeeping(c)],
                    wnsynset=row[2],
                    wnlemmas=[w.strip() for w in row[3].split(",") if w.strip()],
                    up=_vector(row[4], file, line_no, "up", 3),
                    front=_vector(row[5], file, line_no, "front", 3),
                    unit=unit,
                    dims_cm=_vector(row[7], file, line_no, "aligned.dims", 3),
                    name=row[14].strip(),
                    tags=[t.strip() for t in row[15].split(",") if t.strip()],
                )
    except OSError as e:
        raise SceneSuggestError(f"cannot read: {e}", file=file) from None
    return out


def read_field_file(path: str | Path) -> dict[str, list[str]]:
    """Read ``names.txt`` / ``tags.txt`` (``id|value|value…``) into ``{id: [values]}``."""
    path = Path(path)
    out: dict[str, list[str]] = {}
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise SceneSuggestError(f"cannot read: {e}", file=str(path)) from None
    for line in text.splitlines():
        if not line.strip():
            continue
        model_id, *values = line.split("|")
        out[model_id.strip()] = [v.strip() for v in values if v.strip()]
    return out


def camel(text: str) -> str:
    """A WordNet lemma as a category name: ``"picture frame"`` → ``"PictureFrame"``."""
    return "".join(w[:1].upper() + w[1:] for w in re.split(r"[\s_\-]+", text.strip()) if w)


def category_paths(meta: dict[str, ModelMeta]) -> dict[str, list[str]]:
    """Coarse→fine category path of every model.

    The lists are mostly coarse→fine but not always (``Bear,PlushToy,Toy``), so each list is ordered by
    how many models carry each label (more models = coarser), keeping the file's order on ties. Models
    without a label fall back to their first WordNet lemma (``fireplace`` → ``Fireplace``).
    """
    frequency = Counter(label for m in meta.values() for label in set(m.labels))
    paths: dict[str, list[str]] = {}
    for m in meta.values():
        if m.labels:
            unique = list(dict.fromkeys(m.labels))
            paths[m.id] = sorted(unique, key=lambda c: (-frequency[c], unique.index(c)))
        elif m.wnlemmas:
            paths[m.id] = [camel(m.wnlemmas[0])]
    return paths
