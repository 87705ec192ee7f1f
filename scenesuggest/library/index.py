"""The model library: what is known of each 3D model, and the index file that lists them.

A model's *raw* frame is the frame of its source mesh (any units, any up/front); its *canonical* frame
is the one every scene and asset uses: metres, +Y up, +Z front, bbox bottom centred at the origin.
:meth:`ModelInfo.canonical_from_raw` is the one place that maps between the two.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import write_atomically
from ..errors import SceneSuggestError
from ..scenes import frames

INDEX_FILE = "library.json"
INDEX_FORMAT = "scenesuggest-library"
INDEX_VERSION = 1


@dataclass
class ModelInfo:
    """One model. ``size`` is its canonical bbox extent in metres; ``raw_bbox`` the bbox of the source
    mesh in raw model units ((min xyz), (max xyz)); ``unit`` converts raw units to metres.

    ``size_source`` says where the size came from: ``mesh`` (measured), ``metadata`` (ShapeNetSem
    aligned dimensions placed by the scene contacts), ``procedural`` or ``guess``.
    """

    id: str
    category: str
    category_path: list[str]
    name: str = ""
    tags: list[str] = field(default_factory=list)
    description: str = ""
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    front: tuple[float, float, float] = (0.0, 0.0, 1.0)
    unit: float = 1.0
    raw_bbox: tuple[tuple[float, float, float], tuple[float, float, float]] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    size_source: str = "mesh"
    mesh: str | None = None
    asset: str | None = None
    thumbnail: str | None = None

    @property
    def size(self) -> tuple[float, float, float]:
        """Canonical bbox extent (x, y, z) in metres."""
        lo, hi = self._aligned_bbox()
        return tuple(float(v) for v in (hi - lo))

    def _aligned_bbox(self) -> tuple[np.ndarray, np.ndarray]:
        """The raw bbox rotated to +Y up / +Z front and scaled to metres (not yet centred)."""
        lo, hi = self.raw_bbox
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        aligned = corners @ (frames.alignment(self.up, self.front) * self.unit).T
        return aligned.min(axis=0), aligned.max(axis=0)

    def canonical_from_raw(self) -> np.ndarray:
        """4×4 map from raw mesh coordinates to the canonical frame (scale, align, move bottom centre to 0)."""
        lo, hi = self._aligned_bbox()
        bottom_centre = np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])
        return frames.translation(-bottom_centre) @ frames.linear(frames.alignment(self.up, self.front) * self.unit)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["size"] = list(self.size)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ModelInfo:
        d = {k: v for k, v in d.items() if k != "size"}
        d["up"] = tuple(d.get("up", (0, 1, 0)))
        d["front"] = tuple(d.get("front", (0, 0, 1)))
        lo, hi = d.get("raw_bbox", ((0, 0, 0), (0, 0, 0)))
        d["raw_bbox"] = (tuple(lo), tuple(hi))
        return cls(**d)


def save_index(models: dict[str, ModelInfo], directory: str | Path, extra: dict | None = None) -> Path:
    """Write ``library.json`` atomically (a reader never sees half a file)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    doc = {"format": INDEX_FORMAT, "version": INDEX_VERSION, **(extra or {}),
           "models": [m.to_dict() for m in sorted(models.values(), key=lambda m: m.id)]}
    return write_atomically(directory / INDEX_FILE, (json.dumps(doc, indent=1) + "\n").encode("utf-8"))


def load_index(directory: str | Path) -> dict[str, ModelInfo]:
    path = Path(directory) / INDEX_FILE
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise SceneSuggestError(f"cannot read the model library index: {e}", file=str(path)) from None
    if not isinstance(doc, dict) or doc.get("format") != INDEX_FORMAT:
        raise SceneSuggestError(f"not a model library index (expected format {INDEX_FORMAT!r})",
                                file=str(path), field="format")
    try:
        return {m["id"]: ModelInfo.from_dict(m) for m in doc["models"]}
    except (KeyError, TypeError, ValueError) as e:
        raise SceneSuggestError(f"malformed model entry: {e}", file=str(path), field="models") from None
