"""The native scene format: versioned JSON; ``save`` → ``load`` round-trips exactly.

Layout (version 1)::

    {"format": "scenesuggest-scene", "version": 1, "id": "...", "scene_type": "Bedroom", "source": "...",
     "objects": [{"id": "1", "model_id": "...", "category": "Desk", "size": [sx, sy, sz],
                  "transform": [16 numbers, column-major, canonical model frame -> world],
                  "parent": "0" | null, "surface_type": "up_exterior" | null,
                  "attachment_face": "bottom" | null, "contact_point": [x, y, z] | null,
                  "contact_normal": [x, y, z] | null}, ...],
     "walls": [{"normal": [nx, nz], "offset": d, "along": [a0, a1], "height": [y0, y1]}, ...]}

Metres, +Y up. ``walls`` is optional (see :mod:`scenesuggest.scenes.walls`; without it the room object's box gives
them; an empty list says the scene has no walls). Unknown keys are errors, so a typo never silently drops data.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..atomic import write_atomically
from ..errors import SceneSuggestError
from ..jsonpos import LineIndex, loads_with_lines
from . import frames
from .scene import SURFACE_TYPES, ObjectInstance, Scene
from .walls import Wall

FORMAT = "scenesuggest-scene"
VERSION = 1
_TOP_KEYS = {"format", "version", "id", "scene_type", "source", "objects", "walls"}
_WALL_KEYS = {"normal": 2, "offset": 1, "along": 2, "height": 2}
_OBJECT_KEYS = {"id", "model_id", "category", "size", "transform", "parent", "surface_type",
                "attachment_face", "contact_point", "contact_normal"}


def _vec(v) -> list[float] | None:
    return None if v is None else [float(x) for x in v]


def scene_to_dict(scene: Scene) -> dict:
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "id": scene.id,
        "scene_type": scene.scene_type,
        "source": scene.source,
        "objects": [
            {
                "id": o.id,
                "model_id": o.model_id,
                "category": o.category,
                "size": _vec(o.size),
                "transform": frames.to_column_major(o.transform),
                "parent": o.parent,
                "surface_type": o.surface_type,
                "attachment_face": o.attachment_face,
                "contact_point": _vec(o.contact_point),
                "contact_normal": _vec(o.contact_normal),
            }
            for o in scene
        ],
    }
    if scene.walls is not None:
        doc["walls"] = [w.to_dict() for w in scene.walls]
    return doc


def dumps(scene: Scene) -> str:
    return json.dumps(scene_to_dict(scene), indent=1) + "\n"


def save(scene: Scene, path: str | Path) -> None:
    """Write ``scene`` as native JSON, atomically (a server reading the file never sees half a scene)."""
    write_atomically(path, dumps(scene).encode("utf-8"))


def finite(x) -> bool:
    """A JSON number a float holds, finite (booleans are not numbers; an integer too large for a float is not)."""
    try:
        return not isinstance(x, bool) and isinstance(x, int | float) and math.isfinite(x)
    except OverflowError:
        return False


class _Reader:
    """Validates one parsed document, raising errors that name file, line and field."""

    def __init__(self, file: str, index: LineIndex | None):
        self.file = file
        self.index = index

    def fail(self, message: str, obj: object, key: str | None) -> SceneSuggestError:
        line = self.index.line_of(obj, key) if self.index else None
        return SceneSuggestError(message, file=self.file, line=line, field=key)

    def string(self, obj: dict, key: str, *, optional: bool = False) -> str | None:
        v = obj.get(key)
        if v is None and optional:
            return None
        if not isinstance(v, str) or not v:
            raise self.fail("expected a non-empty string" if key in obj else "missing", obj, key)
        return v

    def numbers(self, obj: dict, key: str, n: int, *, optional: bool = False) -> tuple[float, ...] | None:
        v = obj.get(key)
        if v is None and optional:
            return None
        if not isinstance(v, list) or len(v) != n:
            raise self.fail(f"expected a list of {n} numbers" if key in obj else "missing", obj, key)
        for x in v:
            if not finite(x):
                raise self.fail(f"bad number {x!r:.40}", obj, key)
        return tuple(float(x) for x in v)

    def choice(self, obj: dict, key: str, allowed) -> str | None:
        v = obj.get(key)
        if v is not None and v not in allowed:
            raise self.fail(f"{v!r} is not one of {', '.join(allowed)}", obj, key)
        return v

    def unknown(self, obj: dict, allowed: set[str]) -> None:
        for key in obj:
            if key not in allowed:
                raise self.fail("unknown field", obj, key)

    def scene(self, doc: object) -> tuple[Scene, dict[str, int]]:
        if not isinstance(doc, dict):
            raise SceneSuggestError("a scene file must hold a JSON object", file=self.file, line=1)
        self.unknown(doc, _TOP_KEYS)
        if doc.get("format") != FORMAT:
            raise self.fail(f"expected {FORMAT!r}", doc, "format")
        if doc.get("version") != VERSION:
            raise self.fail(f"unsupported version {doc.get('version')!r} (this reader knows {VERSION})",
                            doc, "version")
        source = doc.get("source", "")
        if not isinstance(source, str):
            raise self.fail("expected a string", doc, "source")
        scene = Scene(self.string(doc, "id"), self.string(doc, "scene_type"), source=source)
        objs = doc.get("objects")
        if not isinstance(objs, list):
            raise self.fail("expected a list of objects", doc, "objects")
        lines: dict[str, int] = {}
        for o in objs:
            if not isinstance(o, dict):
                raise self.fail("each object must be a JSON object", doc, "objects")
            inst = self.instance(o)
            if inst.id in scene.objects:
                raise self.fail(f"duplicate object id {inst.id!r}", o, "id")
            scene.objects[inst.id] = inst
            lines[inst.id] = self.index.line_of(o) if self.index else None
        if "walls" in doc:
            scene.walls = self.walls(doc)
        return scene, lines

    def walls(self, doc: dict) -> list[Wall]:
        walls = doc["walls"]
        if not isinstance(walls, list):
            raise self.fail("expected a list of walls", doc, "walls")
        out = []
        for w in walls:
            if not isinstance(w, dict):
                raise self.fail("each wall must be a JSON object", doc, "walls")
            self.unknown(w, set(_WALL_KEYS))
            values = {}
            for key, n in _WALL_KEYS.items():
                if n == 1:
                    v = w.get(key)
                    if not finite(v):
                        raise self.fail("expected a number" if key in w else "missing", w, key)
                    values[key] = float(v)
                else:
                    values[key] = self.numbers(w, key, n)
            if abs(math.hypot(*values["normal"]) - 1.0) > 1e-3:
                raise self.fail("the normal must be a unit vector (nx, nz)", w, "normal")
            for key in ("along", "height"):
                if values[key][0] > values[key][1]:
                    raise self.fail("expected [low, high]", w, key)
            out.append(Wall(**values))
        return out

    def instance(self, o: dict) -> ObjectInstance:
        self.unknown(o, _OBJECT_KEYS)
        size = self.numbers(o, "size", 3)
        if min(size) < 0:
            raise self.fail("sizes must not be negative", o, "size")
        matrix = frames.from_column_major(self.numbers(o, "transform", 16))
        return ObjectInstance(
            id=self.string(o, "id"),
            model_id=self.string(o, "model_id"),
            category=self.string(o, "category"),
            transform=matrix,
            size=size,
            parent=self.string(o, "parent", optional=True),
            surface_type=self.choice(o, "surface_type", SURFACE_TYPES),
            attachment_face=self.choice(o, "attachment_face", frames.FACES),
            contact_point=self.numbers(o, "contact_point", 3, optional=True),
            contact_normal=self.numbers(o, "contact_normal", 3, optional=True),
        )


def loads(text: str, file: str = "<string>") -> Scene:
    """Parse and validate a native scene document; errors name ``file``, the line and the field."""
    try:
        doc, index = loads_with_lines(text)
    except json.JSONDecodeError as e:
        raise SceneSuggestError(f"not valid JSON: {e.msg} (column {e.colno})", file=file, line=e.lineno) from None
    reader = _Reader(file, index)
    scene, lines = reader.scene(doc)
    scene.validate(file=file, lines=lines)
    return scene


def load(path: str | Path) -> Scene:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise SceneSuggestError(f"cannot read: {e}", file=str(path)) from None
    return loads(text, file=str(path))


def from_dict(doc: dict, file: str = "<dict>") -> Scene:
    """Validate an already-parsed document (no line numbers available)."""
    scene, _ = _Reader(file, None).scene(doc)
    scene.validate(file=file)
    return scene
