"""pytest's hooks and the shared fixtures (nothing imports this module: tests import their helpers from support.py,
demostudy.py and the other *help.py modules). Data that lives beside the project (../shared/data) is found here;
tests that need it skip with a reason when it is absent, except under CI=true, where its absence is a failure."""

from __future__ import annotations

import secrets
import sys
from pathlib import Path

import pytest
from demostudy import DEMO_STUDY, make_app
from support import LME4_SEED, REPLICATION, SHARED_DATA, _lme4, lacking, replication_module, require

BROWSER_TESTS = Path(__file__).resolve().parent / "browser"
# the benchmarks' own modules (a crowd, the naive scorer, a large library), which tests check
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))


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


@pytest.fixture(scope="session")
def demo_priors(demo_resources) -> Path:
    """The demo study's priors file (built by ``demo_resources``)."""
    from study_server.studies.study_file import load_study

    return load_study(DEMO_STUDY).priors


# --- engine fixtures shared with the server's tests ----------------------------------------------------------
@pytest.fixture(scope="module")
def learned_file(tmp_path_factory) -> Path:
    """A learned engine trained on the synthetic corpus (seconds), saved."""
    import synthetic

    from scenesuggest import engines

    corpus = synthetic.corpus()
    path = tmp_path_factory.mktemp("learned") / "synthetic.learned.npz"
    engines.kind("learned").train(None, corpus.scenes, corpus.taxonomy, path, seed=0)
    return path


@pytest.fixture(scope="module")
def external(tmp_path_factory):
    """The external engine of tests/external_engine.py in its own process; yields its base URL."""
    import subprocess
    import time

    port_file = tmp_path_factory.mktemp("engine") / "port"
    engine = Path(__file__).resolve().parent / "external_engine.py"
    proc = subprocess.Popen([sys.executable, str(engine), str(port_file)])
    try:
        deadline = time.monotonic() + 10
        while not port_file.exists() or not port_file.read_text():
            assert proc.poll() is None and time.monotonic() < deadline, "the external engine did not start"
            time.sleep(0.02)
        yield f"http://127.0.0.1:{port_file.read_text()}"
    finally:
        proc.kill()
        proc.wait()


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
