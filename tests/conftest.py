"""Shared fixtures. Data that lives beside the project (../shared/data) is found here; tests that need
it skip with a reason when it is absent, except under CI=true, where its absence is a failure."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("SCENESUGGEST_SHARED_DATA", ROOT.parent / "shared" / "data"))
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def require(path: Path, what: str) -> Path:
    if not path.exists():
        message = f"{what} not found at {path} (set SCENESUGGEST_SHARED_DATA)"
        if IN_CI:
            pytest.fail(message + " — required under CI=true")
        pytest.skip(message)
    return path


@pytest.fixture(scope="session")
def stanford_dir() -> Path:
    return require(SHARED_DATA / "stanford_scene_db", "the Stanford Scene Database")


@pytest.fixture(scope="session")
def stanford_meshes() -> Path:
    return require(SHARED_DATA / "stanford_models" / "models", "the Stanford model meshes")


@pytest.fixture(scope="session")
def stanford(stanford_dir, stanford_meshes):
    from scenesuggest.corpora import load_corpus

    return load_corpus(f"stanford:{stanford_dir}", meshes=stanford_meshes)


@pytest.fixture(scope="session")
def ai2thor():
    from scenesuggest.corpora import load_corpus

    return load_corpus("ai2thor")
