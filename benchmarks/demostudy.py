"""The demo study in process, for the benchmarks and the tests: the study server as a Flask app on a fresh
database (driven by its test client), and a participant walked from the entry link to the first trial."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from serverproc import DEMO_STUDY

#: A participant's answers to the demo study's forms (demographics) on the way to the first trial.
DEMOGRAPHICS = {"age": "30", "experience_3d": "Never", "pointing_device": "Mouse"}


def make_app(folder: Path, database_url: str | None = None, studies=None, **config):
    """The study server in process serving ``studies`` (study files; default the demo study), its instance folder
    ``folder``/instance, on ``database_url`` (default: the SQLite file ``folder``/study.sqlite3) with the schema
    migrated to the newest revision. ``config`` overrides the rest: a test set-up (fixed secret key, errors not
    hidden, the studies loaded when first asked for)."""
    from study_server import create_app, upgrade_database

    app = create_app({
        "INSTANCE_PATH": str(folder / "instance"),
        "SQLALCHEMY_DATABASE_URI": database_url or f"sqlite:///{folder / 'study.sqlite3'}",
        "STUDY_FILES": studies or [DEMO_STUDY], "SECRET_KEY": "test-secret", "TESTING": True,
        "WARM_STUDIES": False, **config})
    upgrade_database(app)
    return app


def to_first_trial(transport, pid: str, study: str = "demo"):
    """Participant ``pid`` of ``study`` from the entry link to the first trial over ``transport`` (a
    :mod:`simulation.transport`), answering with :data:`DEMOGRAPHICS`; returns the trial page
    (:class:`simulation.page.Page`: its ``boot`` holds the session token and the trial). RuntimeError when the
    walk stops before it."""
    from simulation.walker import Walker

    page = Walker(transport, study).to_first_trial({"pid": pid}, lambda _: DEMOGRAPHICS)
    if page.step != "trial":
        raise RuntimeError(f"{pid} could not reach the trials (stopped at {page.step!r})")
    return page


def rows_balance(rows_of_completed, study) -> tuple[dict[int, int], bool]:
    """Completed participants per schedule row of ``study`` (loaded: :func:`study_server.study_file.load_study`;
    every row, an empty one counting as none) and whether they are balanced: no two rows differ by more than one
    participant, and someone completed."""
    rows = Counter({r: 0 for r in range(study.n_rows)})
    rows.update(rows_of_completed)
    return dict(sorted(rows.items())), max(rows.values()) - min(rows.values()) <= 1 and rows.total() > 0
