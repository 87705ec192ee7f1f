"""The ``learned`` engine: the paper's factors and the context the paper ignores, ranked by a learned model, and
the reference frame of each heading chosen per query (beyond the paper).

:mod:`.context` counts the context, :mod:`.features` turns a click into rows, :mod:`.training` learns the
ranker and the frame classifier out of fold, :mod:`.engine` answers queries and reads and writes the file.

Options of a study condition: ``file``, the trained file (relative to the study file; default: the study's priors
file with ``.learned.npz`` for ``.npz``, which ``scenesuggest study prepare`` builds for the corpora the server
prepares itself, and ``scenesuggest engine train learned SOURCE -o FILE`` for any); ``frames`` (default false):
turn each suggestion as the frame classifier chooses, not as the paper's engine does (see :mod:`.engine`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...errors import SceneSuggestError
from ..protocol import EngineKind, LoadContext
from .engine import LearnedEngine

OPTIONS = ("file", "frames")
SUFFIX = ".learned.npz"


@dataclass(frozen=True)
class LearnedConfig:
    """A condition's learned engine: its file (None: beside the priors) and whether it turns suggestions by its
    frame classifier."""

    file: Path | None = None
    frames: bool = False


def default_file(priors: Path) -> Path:
    """The learned engine's file beside a study's priors file."""
    return priors.with_name(priors.name.removesuffix(".npz") + SUFFIX)


class LearnedKind(EngineKind):
    name = "learned"
    version = "1"
    summary = ("learning to rank (LightGBM lambdarank) over the paper's factors and the scene's context; with "
               "frames = true, the reference frame of each heading chosen per query")
    trainable = True

    def configure(self, options: Mapping[str, Any], base: Path | None = None) -> LearnedConfig:
        for key in options:
            if key not in OPTIONS:
                raise SceneSuggestError(f"unknown key: this engine takes name, {', '.join(OPTIONS)}", field=key)
        frames = options.get("frames", False)
        if not isinstance(frames, bool):
            raise SceneSuggestError(f"expected true or false, got a value of type {type(frames).__name__}",
                                    field="frames")  # the value itself may be anything, of any length
        file = options.get("file")
        if file is None:
            return LearnedConfig(None, frames)
        if not isinstance(file, str) or not file.strip():
            raise SceneSuggestError("expected the path of a learned engine's file", field="file")
        return LearnedConfig((base / file) if base is not None else Path(file), frames)

    def trained_file(self, config: LearnedConfig, priors: Path) -> Path:
        return config.file if config.file is not None else default_file(priors)

    def load(self, config: LearnedConfig, context: LoadContext) -> LearnedEngine:
        return LearnedEngine.load(self.trained_file(config, context.priors), choose_frames=config.frames)

    def problem(self, config: LearnedConfig, priors: Path, current: bool = False) -> str | None:
        from .engine import code_digest

        path = self.trained_file(config, priors)
        try:
            meta = LearnedEngine.read_meta(path)
        except SceneSuggestError as e:
            return f"no usable learned engine's file at {path} ({e.message})"
        if current and meta.get("code") != code_digest():
            return f"the learned engine's file {path} was trained by other engine code"
        return None

    def fit(self, config, scenes, taxonomy, *, seed: int = 0, progress=None, periods=None) -> LearnedEngine:
        from .training import fit

        engine = fit(scenes, taxonomy, seed=seed, periods=periods, progress=progress)
        return engine.choosing_frames(config is not None and config.frames)

    def train(self, config, scenes, taxonomy, out: Path, *, seed: int = 0, progress=None, periods=None) -> dict:
        engine = self.fit(config, scenes, taxonomy, seed=seed, progress=progress, periods=periods)
        path = engine.save(out)
        return {"out": str(path), "bytes": path.stat().st_size, **engine.meta}


KIND = LearnedKind()

__all__ = ["KIND", "LearnedConfig", "LearnedEngine", "default_file"]
