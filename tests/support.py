"""What tests use besides fixtures: where the shared data is, skipping for want of something (failing instead under
CI=true), the lme4 oracle's seed, and the replication's modules. It brings in neither the server nor the engine (the
demo study's app, copies and served instances are demostudy.py's). Tests import it; pytest's fixtures are in
conftest.py, which nothing imports."""

from __future__ import annotations

import functools
import os
import secrets
import sys
from pathlib import Path
from typing import NoReturn

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The built-in demo study's folder (its study file, scenes and target images): data, read without the server.
DEMO_FOLDER = ROOT / "study_server" / "demo"
SHARED_DATA = Path(os.environ.get("SCENESUGGEST_SHARED_DATA", ROOT.parent / "shared" / "data"))
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")

# The lme4 oracle's random studies (tests/test_lme4_oracle.py): drawn afresh each run unless set. Set here, before
# any worker process starts, so that every worker draws the same studies.
_seed = os.environ.setdefault("SCENESUGGEST_LME4_SEED", str(secrets.randbelow(10**6)))
if not _seed.isdigit():
    raise pytest.UsageError(f"SCENESUGGEST_LME4_SEED must be a whole number ≥ 0, not {_seed!r}")
LME4_SEED = int(_seed)


@functools.cache
def _lme4() -> tuple[str | None, str]:
    """(the Rscript that has lme4 and jsonlite, their versions) or (None, what to install): probed once."""
    import shutil
    import subprocess

    rscript = shutil.which("Rscript")
    if rscript is None:
        return None, "R is not installed (apt-get install r-base-core r-cran-lme4 r-cran-jsonlite)"
    probe = subprocess.run([rscript, "-e", 'library(lme4); library(jsonlite); cat(R.version.string, "| lme4", '
                            'format(packageVersion("lme4")), "| jsonlite", format(packageVersion("jsonlite")))'],
                           capture_output=True, text=True)
    if probe.returncode:
        return None, "R has no lme4 or jsonlite (apt-get install r-cran-lme4 r-cran-jsonlite)"
    return rscript, probe.stdout.strip()


def lacking(message: str) -> NoReturn:
    """Skip the test for want of what ``message`` names (and how to get it); under CI=true, fail it instead."""
    if IN_CI:
        pytest.fail(message + " — required under CI=true")
    pytest.skip(message)


def require_lme4() -> str:
    """The Rscript to run, with lme4 and jsonlite; skips naming what to install (under CI=true: fails)."""
    rscript, said = _lme4()
    if rscript is None:
        lacking(f"the lme4 oracle needs R with lme4 and jsonlite: {said}")
    return rscript


def require_node() -> str:
    """The Node.js executable, to run the client's modules outside a browser, with three.js installed in
    node_modules; skips naming what to install (under CI=true: fails)."""
    import shutil

    node = shutil.which("node")
    if node is None:
        lacking("Node.js is not installed (apt-get install nodejs)")
    if not (ROOT / "node_modules" / "three" / "package.json").is_file():
        lacking("node_modules/three is missing: run 'make setup' (npm ci) first")
    return node


def require_wordnet():
    """The machine's WordNet 3.0 (Debian's wordnet-base); skips naming what to install (under CI=true: fails)."""
    from scenesuggest.corpora.wordnet import wordnet
    from scenesuggest.errors import SceneSuggestError

    try:
        return wordnet()
    except SceneSuggestError as e:
        lacking(str(e))


def require(path: Path, what: str) -> Path:
    if not path.exists():
        lacking(f"{what} not found at {path} (set SCENESUGGEST_SHARED_DATA)")
    return path


REPLICATION = ROOT / "experiments" / "scenesuggest-2015"


def replication_module(name: str):
    """A module of experiments/scenesuggest-2015 (targets, prepare, compare), imported from its file."""
    import importlib

    if str(REPLICATION) not in sys.path:
        sys.path.insert(0, str(REPLICATION))
    return importlib.import_module(name)


