"""The checkout a benchmark measures: the one it lives in. The project is installed (editable) from one checkout;
to measure another — e.g. a ``git worktree`` of an earlier commit, to compare — put that checkout first on the
import path (``PYTHONPATH=<checkout>``), as :func:`env_for` does for a subprocess."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

#: The project's packages.
PACKAGES = ("scenesuggest", "study_server", "simulation", "analysis")


def imported_from(package: str) -> Path | None:
    """The folder holding ``package`` as this process imports it (its checkout), or None when it is not found."""
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(spec.submodule_search_locations[0]).resolve().parent


def require(root: Path, packages: tuple[str, ...] = PACKAGES) -> None:
    """Stop (SystemExit, saying what to set) unless each of ``packages`` is imported from checkout ``root``."""
    root = root.resolve()
    elsewhere = {p: imported_from(p) for p in packages}
    elsewhere = {p: where for p, where in elsewhere.items() if where != root}
    if elsewhere:
        found = ", ".join(f"{p} from {where or 'nowhere'}" for p, where in elsewhere.items())
        raise SystemExit(f"this benchmark measures the checkout {root} but imports {found}: the checkout must "
                         f"hold them and come first on the import path (PYTHONPATH={root})")


def env_for(root: Path) -> dict[str, str]:
    """This process's environment with checkout ``root`` first on PYTHONPATH: a subprocess run with it imports the
    project's packages from ``root``."""
    paths = [str(root.resolve()), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(paths)}
