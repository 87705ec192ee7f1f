"""Shared fixtures. Data that lives beside the project (../shared/data) is found here; tests that need
it skip with a reason when it is absent, except under CI=true, where its absence is a failure."""

from __future__ import annotations

import contextlib
import functools
import os
import secrets
import sys
from pathlib import Path
from typing import NoReturn

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("SCENESUGGEST_SHARED_DATA", ROOT.parent / "shared" / "data"))
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")
# serverproc (the server as a subprocess) and demostudy (the demo study in process), shared with the benchmarks
sys.path.insert(0, str(ROOT / "benchmarks"))
from demostudy import DEMO_STUDY, make_app  # noqa: E402

BROWSER_TESTS = Path(__file__).resolve().parent / "browser"
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


def pytest_report_header(config) -> list[str]:
    """The lme4 oracle's seed, and the R and lme4 it runs against."""
    return [f"lme4 oracle: seed {LME4_SEED} (SCENESUGGEST_LME4_SEED={LME4_SEED} repeats this run's studies)",
            f"lme4 oracle: {_lme4()[1]}"]


def pytest_collection_modifyitems(config, items) -> None:
    """Mark what needs Chromium (``browser``: every test under tests/browser/) or a PostgreSQL server
    (``postgresql``), so that ``make test-fast`` can leave them out; ``slow`` is set by hand on the longest tests."""
    for item in items:
        if item.path.resolve().is_relative_to(BROWSER_TESTS):
            item.add_marker(pytest.mark.browser)
        names = set(getattr(item, "fixturenames", ()))
        params = getattr(getattr(item, "callspec", None), "params", {})
        if {"postgres_server", "postgres_db"} & names or "postgresql" in params.values():
            item.add_marker(pytest.mark.postgresql)


def require(path: Path, what: str) -> Path:
    if not path.exists():
        lacking(f"{what} not found at {path} (set SCENESUGGEST_SHARED_DATA)")
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


def copy_demo_study(tmp: Path) -> Path:
    """The demo study copied into ``tmp``/demo (its targets may then be written), its resources still the
    server's own; returns the copy's study file."""
    import shutil

    folder = tmp / "demo"
    shutil.copytree(DEMO_STUDY.parent, folder)
    return folder / "study.toml"


REPLICATION = ROOT / "experiments" / "scenesuggest-2015"


def replication_module(name: str):
    """A module of experiments/scenesuggest-2015 (targets, prepare, compare), imported from its file."""
    import importlib

    if str(REPLICATION) not in sys.path:
        sys.path.insert(0, str(REPLICATION))
    return importlib.import_module(name)


@pytest.fixture(scope="session")
def replication(stanford_dir, stanford_meshes) -> Path:
    """The replication study prepared from ../shared/data as `make replication` prepares it (library, priors,
    targets under var/; steps whose inputs have not changed are skipped); yields its study file."""
    prepare = replication_module("prepare")
    prepare.prepare(stanford_dir, meshes=stanford_meshes, log=lambda *_: None)
    return REPLICATION / "study.toml"


# --- study server fixtures ------------------------------------------------------------------------------------
@pytest.fixture(scope="session")
def demo_resources():
    """The demo study, with the server's own priors and model library for it (built here when missing or made
    by other engine code, as `make demo` builds them)."""
    from study_server.studies.prepare import prepare
    from study_server.studies.study_file import load_study

    prepare(load_study(DEMO_STUDY), lambda items, label="": items, lambda message: None)
    return DEMO_STUDY


@contextlib.contextmanager
def gunicorn(tmp: Path, workers: int = 2):
    """The study server as `make serve` runs it (gunicorn, the demo study) on a fresh SQLite database in ``tmp``
    and a free loopback port; yields (base URL, database path)."""
    from serverproc import StudyServer

    database = tmp / "study.sqlite3"
    make_app(tmp, f"sqlite:///{database}")  # migrated here, before the workers start
    with StudyServer(tmp / "instance", f"sqlite:///{database}", workers, migrate=False) as server:
        yield server.base, database


@pytest.fixture
def app(tmp_path, demo_resources):
    return make_app(tmp_path)


@pytest.fixture
def client(app):
    return app.test_client()


@pytest.fixture(scope="session")
def postgres_server():
    """A throwaway PostgreSQL server on loopback (TESTING.md); skipped when PostgreSQL is not installed."""
    from serverproc import ThrowawayPostgres

    try:
        server = ThrowawayPostgres()
    except RuntimeError as e:
        lacking(str(e))
    with server:
        yield server


@pytest.fixture
def postgres_db(postgres_server):
    """A fresh database on the throwaway server for one test."""
    import secrets

    return postgres_server.create("t" + secrets.token_hex(6))


@pytest.fixture(params=["sqlite", "postgresql"])
def backend_url(request, tmp_path, demo_resources):
    """A fresh database for one test, on SQLite and (a second run of the test) on the throwaway PostgreSQL."""
    if request.param == "postgresql":
        return request.getfixturevalue("postgres_db")
    return f"sqlite:///{tmp_path / 'study.sqlite3'}"


@pytest.fixture
def app_on(backend_url, tmp_path):
    """The demo study's app on ``backend_url``, its admin password integrityhelp.PASSWORD."""
    from integrityhelp import PASSWORD
    from werkzeug.security import generate_password_hash

    return make_app(tmp_path, backend_url, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
