"""Reader for the Stanford Scene Database v1.0 text format (one block of fields per object).

Only parsing and checking live here; conversion to the world frame is in :mod:`.stanford`.
Every error names the file, the line and the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SceneSuggestError

#: field name → number of values (None: any number of integers, for ``children``)
FIELDS: dict[str, int | None] = {
    "parentIndex": 1,
    "children": None,
    "parentMaterialGroupIndex": 1,
    "parentTriangleIndex": 1,
    "parentUV": 2,
    "parentContactPosition": 3,
    "parentContactNormal": 3,
    "parentOffset": 3,
    "scale": 1,
    "transform": 16,
}
INTEGER_FIELDS = {"parentIndex", "children", "parentMaterialGroupIndex", "parentTriangleIndex"}
REQUIRED = ("parentIndex", "parentContactPosition", "parentContactNormal", "transform")


@dataclass
class RawObject:
    """One ``newModel`` block, in the file's units (inches, +Z up)."""

    index: int
    model_id: str
    line: int
    values: dict[str, list[float]] = field(default_factory=dict)
    lines: dict[str, int] = field(default_factory=dict)

    @property
    def parent_index(self) -> int:
        return int(self.values["parentIndex"][0])

    @property
    def transform(self) -> np.ndarray:
        """Model → world, from the file's 16 column-major numbers."""
        return np.asarray(self.values["transform"], dtype=float).reshape(4, 4).T

    @property
    def contact(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(point, normal) on the parent, or None for a root."""
        n = np.asarray(self.values["parentContactNormal"], dtype=float)
        if self.parent_index < 0 or not np.any(n):
            return None
        return np.asarray(self.values["parentContactPosition"], dtype=float), n / np.linalg.norm(n)


def _number(token: str, integer: bool, file: str, line: int, name: str) -> float:
    try:
        value = int(token) if integer else float(token)
    except ValueError:
        kind = "integer" if integer else "number"
        raise SceneSuggestError(f"bad {kind} {token!r}", file=file, line=line, field=name) from None
    if not math.isfinite(value):
        raise SceneSuggestError(f"bad number {token!r}", file=file, line=line, field=name)
    return value


def parse_scene_text(text: str, file: str) -> list[RawObject]:
    """Parse one scene file; raise :class:`SceneSuggestError` naming file, line and field on bad input."""
    objects: list[RawObject] = []
    header: dict[str, str] = {}
    current: RawObject | None = None
    for line_no, raw in enumerate(text.splitlines(), start=1):
        tokens = raw.split()
        if not tokens:
            continue
        name, args = tokens[0], tokens[1:]
        if current is None and name in ("StanfordSceneDatabase", "version", "modelCount"):
            header[name] = " ".join(args)
            if name == "modelCount":
                _number(args[0] if args else "", True, file, line_no, name)
            continue
        if name == "newModel":
            if len(args) != 2:
                raise SceneSuggestError("expected 'newModel <index> <modelId>'", file=file, line=line_no,
                                        field=name)
            index = int(_number(args[0], True, file, line_no, name))
            if index != len(objects):
                raise SceneSuggestError(f"model index {index} out of sequence (expected {len(objects)})",
                                        file=file, line=line_no, field=name)
            current = RawObject(index, args[1], line_no)
            objects.append(current)
            continue
        if name not in FIELDS:
            raise SceneSuggestError("unknown field", file=file, line=line_no, field=name)
        if current is None:
            raise SceneSuggestError("field before the first 'newModel'", file=file, line=line_no, field=name)
        if name in current.values:
            raise SceneSuggestError("field given twice for one model", file=file, line=line_no, field=name)
        expected = FIELDS[name]
        if expected is not None and len(args) != expected:
            raise SceneSuggestError(f"expected {expected} numbers, got {len(args)}", file=file, line=line_no,
                                    field=name)
        current.values[name] = [_number(a, name in INTEGER_FIELDS, file, line_no, name) for a in args]
        current.lines[name] = line_no
    _check(objects, header, file)
    return objects


def _check(objects: list[RawObject], header: dict[str, str], file: str) -> None:
    if "StanfordSceneDatabase" not in header and not objects:
        raise SceneSuggestError("not a Stanford Scene Database file (no 'StanfordSceneDatabase' header)",
                                file=file, line=1)
    if "modelCount" in header and int(header["modelCount"]) != len(objects):
        raise SceneSuggestError(f"modelCount says {header['modelCount']} but the file has {len(objects)} models",
                                file=file, field="modelCount")
    for o in objects:
        for name in REQUIRED:
            if name not in o.values:
                raise SceneSuggestError(f"model {o.index} has no {name}", file=file, line=o.line, field=name)
        p = o.parent_index
        if p >= len(objects) or p < -1 or p == o.index:
            raise SceneSuggestError(f"parentIndex {p} refers to no other model of this scene", file=file,
                                    line=o.lines["parentIndex"], field="parentIndex")
        for c in o.values.get("children", []):
            if not 0 <= c < len(objects) or objects[int(c)].parent_index != o.index:
                raise SceneSuggestError(f"child {int(c)} does not name model {o.index} as its parent",
                                        file=file, line=o.lines["children"], field="children")
        linear = o.transform[:3, :3]
        norms = np.linalg.norm(linear, axis=0)
        if not np.all(norms > 0) or abs(np.linalg.det(linear)) < 1e-9 * np.prod(norms):
            raise SceneSuggestError("singular transform", file=file, line=o.lines["transform"],
                                    field="transform")


def read_scene_file(path: str | Path) -> list[RawObject]:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="strict")
    except (OSError, UnicodeDecodeError) as e:
        raise SceneSuggestError(f"cannot read: {e}", file=str(path)) from None
    return parse_scene_text(text, str(path))
