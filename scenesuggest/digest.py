"""A short hash of some of the engine's own source files: what decides whether a learned or built artefact (a
priors file, a model library) was made by the code now installed, so that artefacts the server builds for
itself are rebuilt when that code changes."""

from __future__ import annotations

import hashlib
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
#: The engine's code up to what it learns and how it is evaluated (the shared modules, every stage but the model
#: assets' builders and the engines by name, and the models' rotational symmetry, which evaluation and the learned
#: engine fold angles by): what a priors file depends on.
ENGINE_SOURCES = ("*.py", "scenes/*.py", "contract/*.py", "library/*.py", "corpora/*.py", "learning/*.py",
                  "suggestion/*.py", "evaluation/*.py", "assets/symmetry.py")


def source_digest(*patterns: str) -> str:
    """16 hex digits of the SHA-256 over the package's files matching ``patterns`` (globs relative to the
    package), in sorted order."""
    digest = hashlib.sha256()
    for path in sorted({p for pattern in patterns for p in PACKAGE.glob(pattern)}):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]
